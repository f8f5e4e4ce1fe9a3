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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.description.naming import sensor_frame, sensor_rate
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.rates import Sampled
from simbot.sim.kit.sensors import ChannelNoise
from simbot.sim.loop.system import Batch, SystemContext, UpdateInfo
from simbot.sim.physics.protocols import FrameMotions
from simbot.transform import rotate_many

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


NOISE_ROWS = 256
"""White-noise draws taken from an IMU's random stream at a time, a row (gyro x y z, accel x y z)
per sample: the same numbers, in the same order, as six drawn each sample, for a sixth of the calls."""


class Imu(Sampled):
    """sensor_msgs/Imu at the sensor's rate in its frame, stamped with the sim time of the sample.

    The loop steps a world's IMUs together (`post_update_all`): one query of every frame, and the
    rotations and noise as arrays. Each keeps its own rate, stream and state; an IMU no one
    subscribes to still samples and draws its noise (what it publishes later does not depend on
    who listened before) but builds no message."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        spec = self.params = ImuParams.from_sdf(sensor)
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self._physics = ctx.physics
        self._where = (model, link.name, sensor.pose)
        self._gravity = np.asarray(ctx.world.gravity, dtype=float)
        self._rng = ctx.rng
        self._gyro = ChannelNoise(spec.angular_velocity_noise, ctx.rng)
        self._accel = ChannelNoise(spec.linear_acceleration_noise, ctx.rng)
        self._covariances = (np.zeros(9), self._gyro.covariance(), self._accel.covariance())
        self._noise_terms = self._terms()
        self._frame = ctx.bus.frame(sensor_frame(sensor))
        self._last_ns: int | None = None
        self._last_linear = np.zeros(3)
        self._white = np.empty((0, 6))
        self._cohort: _Cohort | None = None
        """The IMUs it is sampled with, which hold its state while it is (`_Cohort`)."""
        self._pub = ctx.bus.publisher(ctx.sensor_topic("imu"), messages.Imu)

    def post_update(self, info: UpdateInfo) -> None:
        if self.next_due_ns <= info.sim_time_ns:
            type(self).post_update_all([Batch([self], info)])

    @classmethod
    def post_update_all(cls, batches: Sequence[Batch]) -> None:
        """Every IMU handed (each due now) samples, every world's in one pass (a frame query a
        world); those someone subscribes to publish."""
        due: list[Imu] = []
        stamps: list[int] = []
        parts: list[FrameMotions] = []
        gravities = []
        for here, info in batches:  # those due (the loop hands a paced class no other)
            if here:
                due += here
                stamps += [info.sim_time_ns] * len(here)
                parts.append(here[0]._physics.frame_motions([imu._where for imu in here]))
                gravities.append(np.broadcast_to(here[0]._gravity, (len(here), 3)))  # one a world
        if not due:
            return
        motions = FrameMotions.joined(parts)
        count = len(due)
        rows = _cohort_of(due)
        now = np.asarray(stamps, dtype=np.int64)
        seconds = np.where(rows.last_ns >= 0, (now - rows.last_ns) / 1e9, np.inf)
        acceleration = np.where(np.isfinite(seconds)[:, None], (motions.linear - rows.last) / seconds[:, None], 0.0)
        rows.last, rows.last_ns = motions.linear, now
        # gyro and accelerometer turned into each frame in one call: rows 0..N-1 and N..2N-1
        turns = np.concatenate([motions.orientations, motions.orientations])
        gravity = gravities[0] if len(gravities) == 1 else np.concatenate(gravities)
        sensed = rotate_many(turns, np.concatenate([motions.angular, acceleration - gravity]), into=True)
        terms = rows.terms  # mean, bias, stddev of the six channels
        true = np.hstack([sensed[:count], sensed[count:]])
        measured = true + terms[:, :6] + terms[:, 6:12] + rows.white() * terms[:, 12:]  # ChannelNoise's sum
        Sampled.sampled_all(due, stamps)
        for row in [row for row, imu in enumerate(due) if imu._pub.has_subscribers]:
            imu, quat = due[row], motions.orientations[row]
            imu._pub.put(
                messages.imu(stamps[row], imu._frame, quat, measured[row, :3], measured[row, 3:], imu._covariances)
            )

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        if self._cohort is not None:
            self._cohort.leave()
        self._last_ns = None
        self._white = np.empty((0, 6))
        self._gyro.draw_bias()
        self._accel.draw_bias()
        self._noise_terms = self._terms()

    def _terms(self) -> npt.NDArray[np.float64]:
        """The six channels' mean, bias (drawn at start and each reset) and stddev, end to end."""
        gyro, accel = self._gyro, self._accel
        return np.concatenate([gyro.mean, accel.mean, gyro.bias, accel.bias, gyro.stddev, accel.stddev])


class _Cohort:
    """The IMUs sampled together at the last step, their state as rows: the velocity and time of
    each one's last sample, its noise terms, and the white draws it has ahead (each IMU's own
    stream, taken NOISE_ROWS at a time as `Imu` alone would). A fleet's IMUs come together step
    after step: their state stays here, and goes back into each IMU (`leave`) when another set
    comes or one of them resets."""

    def __init__(self, imus: list[Imu]) -> None:
        self.imus = imus
        self.terms = np.array([imu._noise_terms for imu in imus]).reshape(len(imus), 18)
        self.last = np.array([imu._last_linear for imu in imus]).reshape(len(imus), 3)
        self.last_ns = np.array([-1 if imu._last_ns is None else imu._last_ns for imu in imus], dtype=np.int64)
        self._fill([imu._white for imu in imus])
        for imu in imus:
            imu._cohort = self

    def _fill(self, ahead: list[npt.NDArray[np.float64]]) -> None:
        """Each IMU's draws ahead side by side; one with none left draws its next NOISE_ROWS."""
        ahead = [
            rows if len(rows) else imu._rng.normal(0.0, 1.0, (NOISE_ROWS, 6)) for imu, rows in zip(self.imus, ahead)
        ]
        self._ends = np.array([len(rows) for rows in ahead])
        self._block = np.zeros((len(ahead), int(self._ends.max()), 6))
        for row, rows in enumerate(ahead):
            self._block[row, : len(rows)] = rows
        self._cursor, self._until = 0, int(self._ends.min())

    def _ahead(self) -> list[npt.NDArray[np.float64]]:
        return [self._block[row, self._cursor : end] for row, end in enumerate(self._ends.tolist())]

    def white(self) -> npt.NDArray[np.float64]:
        """The six channels' white draws of each IMU's next sample."""
        if self._cursor == self._until:
            self._fill(self._ahead())
        white = self._block[:, self._cursor]
        self._cursor += 1
        return white

    def leave(self) -> None:
        """Each IMU's state back into it, and the cohort gone."""
        for imu, last, last_ns, ahead in zip(self.imus, self.last, self.last_ns.tolist(), self._ahead()):
            imu._last_linear, imu._last_ns, imu._white = last.copy(), None if last_ns < 0 else last_ns, ahead.copy()
            imu._cohort = None


def _cohort_of(imus: list[Imu]) -> _Cohort:
    """The cohort of `imus`: the one they are in when it holds just them (a comparison of
    identities), else a new one, the state of any they were in back in its IMUs first."""
    held = imus[0]._cohort
    if held is not None and held.imus == imus:
        return held
    for imu in imus:
        if imu._cohort is not None:
            imu._cohort.leave()
    return _Cohort(list(imus))
