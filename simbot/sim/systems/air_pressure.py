"""Air pressure (SDF `air_pressure`): the static pressure of the world's atmosphere at the sensor's height.

Gazebo's model (gz-sensors, after RotorS): the height h is `<reference_altitude>` plus the
sensor's world z; its geopotential height H = R·h/(R + h) with R = 6356766 m; the temperature
there T = T0 + L·H; the pressure P = P0·(T0/T)^(g·M/(R*·L)), the barometric formula of a layer with
lapse rate L (g 9.80665 m/s², M 28.9644 kg/kmol, R* 8314.32 J/(kmol·K)); with L = 0 the
isothermal P0·exp(−g·M·H/(R*·T0)). T0, P0 and L are the world's `<atmosphere>` (SDF defaults
288.15 K, 101325 Pa, −0.0065 K/m: Gazebo's constants). The SDF's noise is added in pascal, and
its variance σ² goes in the message (Gazebo's sensor writes √σ there, which is not a variance).
Published as sensor_msgs/FluidPressure on `<topic>` or Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/air_pressure`.

SDF parameters (under `<air_pressure>`; `AirPressureParams`):

| element | default | meaning |
| --- | --- | --- |
| `<reference_altitude>` | 0 | metres added to the sensor's world z (a mountain without the model) |
| `<pressure><noise>` | none | gaussian noise of the pressure (Pa) |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from simbot.bus import messages
from simbot.description.model import Atmosphere, Sensor
from simbot.sim.sensor_params import ChannelNoise, Noise, SdfElement
from simbot.sim.system import Sampled, SystemContext, UpdateInfo, sensor_frame, sensor_rate

EARTH_RADIUS = 6356766.0
"""m, the radius geopotential height is reckoned with (US Standard Atmosphere 1976)."""
GRAVITY = 9.80665
MOLAR_MASS = 28.9644
"""kg/kmol of dry air."""
GAS_CONSTANT = 8314.32
"""J/(kmol·K)."""


def pressure_at(height: float, atmosphere: Atmosphere) -> float:
    """Pa at `height` metres above sea level in an atmosphere of constant lapse rate (module docstring)."""
    geopotential = EARTH_RADIUS * height / (EARTH_RADIUS + height)
    t0, lapse = atmosphere.temperature, atmosphere.temperature_gradient
    if lapse == 0:
        return atmosphere.pressure * math.exp(-GRAVITY * MOLAR_MASS * geopotential / (GAS_CONSTANT * t0))
    exponent = GRAVITY * MOLAR_MASS / (GAS_CONSTANT * lapse)
    return atmosphere.pressure * (t0 / (t0 + lapse * geopotential)) ** exponent


@dataclass(frozen=True)
class AirPressureParams:
    """An air pressure sensor's SDF parameters (the table in the module docstring)."""

    reference_altitude: float = 0.0
    noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> AirPressureParams:
        element = SdfElement.of(sensor).child_or_empty("air_pressure")
        return AirPressureParams(element.number("reference_altitude", 0.0), element.noise_of("pressure"))


class AirPressure(Sampled):
    """sensor_msgs/FluidPressure at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = AirPressureParams.from_sdf(sensor)
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self._physics = ctx.physics
        self._where = (model, link.name, sensor.pose)
        self._atmosphere = ctx.world.atmosphere
        self._noise = ChannelNoise((self.params.noise,), ctx.rng)
        self._frame = sensor_frame(sensor)
        self._pub = ctx.bus.publisher(ctx.sensor_topic("air_pressure"), messages.FluidPressure)

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        height = self.params.reference_altitude + self._physics.frame_pose(*self._where)[0][2]
        (pressure,) = self._noise((pressure_at(height, self._atmosphere),))
        variance = float(self._noise.variances()[0])
        self._pub.put(messages.fluid_pressure(info.sim_time_ns, self._frame, pressure, variance))
        self.published(info.sim_time_ns)

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        self._noise.draw_bias()
