"""Altimeter (SDF `altimeter`): height of the sensor over where it started, and its vertical speed.

As Gazebo's: the vertical reference is the sensor's world height when the world was built (a
reset keeps it); `vertical_position` is the height now minus that reference, `vertical_velocity`
the world-frame vertical speed of the sensor's origin, each with its own SDF noise (mean, bias
drawn per run, white σ). Published as ros_gz_interfaces/Altimeter, the type ros_gz_bridge gives
Gazebo's, on `<topic>` or Gazebo's `world/<w>/model/<m>/link/<l>/sensor/<s>/altimeter`.

SDF parameters (under `<altimeter>`; `AltimeterParams`):

| element | default | meaning |
| --- | --- | --- |
| `<vertical_position><noise>` | none | gaussian noise of the height (m) |
| `<vertical_velocity><noise>` | none | gaussian noise of the vertical speed (m/s) |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.sim.sensor_params import ChannelNoise, Noise, SdfElement
from simbot.sim.system import Sampled, SystemContext, UpdateInfo, sensor_frame, sensor_rate


@dataclass(frozen=True)
class AltimeterParams:
    """An altimeter's SDF parameters (the table in the module docstring)."""

    position_noise: Noise = Noise()
    velocity_noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> AltimeterParams:
        element = SdfElement.of(sensor).child_or_empty("altimeter")
        return AltimeterParams(element.noise_of("vertical_position"), element.noise_of("vertical_velocity"))


class Altimeter(Sampled):
    """ros_gz_interfaces/Altimeter at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = AltimeterParams.from_sdf(sensor)
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self._physics = ctx.physics
        self._where = (model, link.name, sensor.pose)
        self._reference = self._physics.frame_pose(*self._where)[0][2]
        self._noise = ChannelNoise((self.params.position_noise, self.params.velocity_noise), ctx.rng)
        self._frame = sensor_frame(sensor)
        self._pub = ctx.bus.publisher(ctx.sensor_topic("altimeter"), messages.Altimeter)

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        (position, _), velocity, _ = self._physics.frame_motion(*self._where)
        height, speed = self._noise((position[2] - self._reference, velocity[2]))
        self._pub.put(messages.altimeter(info.sim_time_ns, self._frame, height, speed, self._reference))
        self.published(info.sim_time_ns)

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        self._noise.draw_bias()
