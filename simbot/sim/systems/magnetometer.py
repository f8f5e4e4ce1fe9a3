"""Magnetometer (SDF `magnetometer`): the world's magnetic field seen from the sensor's frame.

As Gazebo's: the world's `<magnetic_field>` (tesla, world frame; SDF default 5.5645e-6
22.8758e-6 −42.3884e-6) rotated into the sensor frame by the inverse of the sensor's world
orientation, so the reading turns as the body turns; then each axis' SDF noise (mean, bias drawn
per run, white σ). Published as sensor_msgs/MagneticField (tesla, each axis' σ² on the
covariance's diagonal; 0 where there is no noise, which ROS reads as unknown) on `<topic>` or
Gazebo's `world/<w>/model/<m>/link/<l>/sensor/<s>/magnetometer`.

SDF parameters (under `<magnetometer>`; `MagnetometerParams`):

| element | default | meaning |
| --- | --- | --- |
| `<x>`, `<y>`, `<z>` `<noise>` | none | gaussian noise of each axis (T) |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.transform import rotate_into


@dataclass(frozen=True)
class MagnetometerParams:
    """A magnetometer's SDF parameters (the table in the module docstring)."""

    noise: tuple[Noise, Noise, Noise] = (Noise(), Noise(), Noise())

    @staticmethod
    def from_sdf(sensor: Sensor) -> MagnetometerParams:
        element = SdfElement.of(sensor).child_or_empty("magnetometer")
        x, y, z = (element.noise_of(axis) for axis in "xyz")
        return MagnetometerParams((x, y, z))


class Magnetometer(FramedSensor):
    """sensor_msgs/MagneticField at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        self.params = MagnetometerParams.from_sdf(ctx.require_sensor()[2])
        super().__init__(ctx, self.params.noise, "magnetometer", messages.MagneticField)
        self._field = np.asarray(ctx.world.magnetic_field, dtype=float)

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        _, quat = self.physics.frame_pose(*self.where)
        local = self.noise(rotate_into(quat, self._field))
        self.publish(info, messages.magnetic_field(info.sim_time_ns, self.frame, local, self.noise.variances()))
