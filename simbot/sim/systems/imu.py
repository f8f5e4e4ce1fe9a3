"""IMU (SDF `imu`): angular velocity, specific force and orientation of its frame, with the SDF's noise.

Linear acceleration is what an accelerometer measures, the specific force a − g: at rest it
reads +9.8 m/s² up. `a` is the change of the frame origin's velocity between two samples divided
by their interval, the mean acceleration over it, as a real IMU's output filter gives; the first
sample after start or reset has no interval and takes a = 0 (the world starts at rest).
Orientation is the frame's in the world (ENU), as Gazebo's IMU reports it by default.
Noise per axis, as gz-sensors applies it: mean + a bias drawn once per run (N(bias_mean,
bias_stddev), random sign) + white N(0, stddev); covariances carry the variances. The key is
`<topic>`, else Gazebo's `world/<w>/model/<m>/link/<l>/sensor/<s>/imu`.

SDF parameters (under `<imu>`; `ImuParams`):

| element | default | meaning |
| --- | --- | --- |
| `<angular_velocity><x|y|z><noise>` | none | gaussian noise of each gyro axis (`mean`, `stddev`, `bias_mean`, `bias_stddev`) |
| `<linear_acceleration><x|y|z><noise>` | none | the same for each accelerometer axis |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.sim.kit.rates import Sampled
from simbot.sim.kit.sensor_params import ChannelNoise, Noise, SdfElement
from simbot.sim.loop.naming import sensor_frame, sensor_rate
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.transform import rotate_into

Axes = tuple[Noise, Noise, Noise]
"""What each axis applies (no noise: Noise())."""


def _axes(element: SdfElement) -> Axes:
    x, y, z = (element.noise_of(axis) for axis in "xyz")
    return (x, y, z)


@dataclass(frozen=True)
class ImuParams:
    """An IMU's SDF parameters (the table in the module docstring)."""

    angular_velocity_noise: Axes = (Noise(), Noise(), Noise())
    linear_acceleration_noise: Axes = (Noise(), Noise(), Noise())

    @staticmethod
    def from_sdf(sensor: Sensor) -> ImuParams:
        imu = SdfElement.of(sensor).child_or_empty("imu")
        return ImuParams(
            _axes(imu.child_or_empty("angular_velocity")), _axes(imu.child_or_empty("linear_acceleration"))
        )


class Imu(Sampled):
    """sensor_msgs/Imu at the sensor's rate in its frame, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        spec = self.params = ImuParams.from_sdf(sensor)
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self._physics = ctx.physics
        self._where = (model, link.name, sensor.pose)
        self._gravity = np.asarray(ctx.world.gravity, dtype=float)
        self._gyro = ChannelNoise(spec.angular_velocity_noise, ctx.rng)
        self._accel = ChannelNoise(spec.linear_acceleration_noise, ctx.rng)
        self._covariances = (np.zeros(9), self._gyro.covariance(), self._accel.covariance())
        self._frame = ctx.bus.frame(sensor_frame(sensor))
        self._last: tuple[int, npt.NDArray[np.float64]] | None = None
        self._pub = ctx.bus.publisher(ctx.sensor_topic("imu"), messages.Imu)

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self.due(info):
            return
        (_, quat), linear_xyz, angular_xyz = self._physics.frame_motion(*self._where)
        linear = np.array(linear_xyz)
        acceleration = np.zeros(3)
        if self._last is not None and now_ns > self._last[0]:
            acceleration = (linear - self._last[1]) / ((now_ns - self._last[0]) / 1e9)
        self._last = (now_ns, linear)
        gyro = self._gyro(rotate_into(quat, angular_xyz))
        accel = self._accel(rotate_into(quat, acceleration - self._gravity))
        self._pub.put(messages.imu(now_ns, self._frame, quat, gyro, accel, self._covariances))
        self.published(now_ns)

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        self._last = None
        self._gyro.draw_bias()
        self._accel.draw_bias()
