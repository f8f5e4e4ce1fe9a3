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
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemContext, UpdateInfo

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


class AirPressure(FramedSensor):
    """sensor_msgs/FluidPressure at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        self.params = AirPressureParams.from_sdf(ctx.require_sensor()[2])
        super().__init__(ctx, (self.params.noise,), "air_pressure", messages.FluidPressure)
        self._atmosphere = ctx.world.atmosphere
        self._variance = float(self.noise.variances()[0])

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        height = self.params.reference_altitude + self.physics.frame_pose(*self.where)[0][2]
        (pressure,) = self.noise((pressure_at(height, self._atmosphere),))
        self.publish(info, messages.fluid_pressure(info.sim_time_ns, self.frame, pressure, self._variance))
