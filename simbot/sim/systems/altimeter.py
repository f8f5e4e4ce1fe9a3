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
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemContext, UpdateInfo


@dataclass(frozen=True)
class AltimeterParams:
    """An altimeter's SDF parameters (the table in the module docstring)."""

    position_noise: Noise = Noise()
    velocity_noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> AltimeterParams:
        element = SdfElement.of(sensor).child_or_empty("altimeter")
        return AltimeterParams(element.noise_of("vertical_position"), element.noise_of("vertical_velocity"))


class Altimeter(FramedSensor):
    """ros_gz_interfaces/Altimeter at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        self.params = spec = AltimeterParams.from_sdf(ctx.require_sensor()[2])
        super().__init__(ctx, (spec.position_noise, spec.velocity_noise), "altimeter", messages.Altimeter)
        self._reference = self.physics.frame_pose(*self.where)[0][2]

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        (position, _), velocity, _ = self.physics.frame_motion(*self.where)
        height, speed = self.noise((position[2] - self._reference, velocity[2]))
        self.publish(info, messages.altimeter(info.sim_time_ns, self.frame, height, speed, self._reference))
