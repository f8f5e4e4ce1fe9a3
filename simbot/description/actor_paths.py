"""Where an actor's script puts it at a sim time, as gz-sim computes it (its rendering SceneManager's
ActorTrajectoryAt, over gz-common's TrajectoryInfo and PoseAnimation, over gz-math's splines).

- The trajectories play in sequence, the first after `delay_start`; each lasts from its first
  waypoint's time to its last's. Before the delay the actor stands at the script's start.
- With `loop` the sequence repeats; without, the actor stays where the last trajectory ends.
- Within a trajectory, the position follows a cubic Hermite spline through the waypoints, in each
  segment's time fraction, with gz-math's tangents: half the chord to the neighbours, times
  (1 − tension), the ends' from their one neighbour (a closed path, first point = last, wraps). Two
  waypoints at tension 0 give p0 + d·(1.5 s² − s³ + 0.5 s): at the start, the middle and the end
  where linear interpolation is, easing in and out between.
- The orientation follows gz-math's rotation spline: squad between the waypoints' quaternions,
  the shortest way round, with tangents from the neighbours' logarithms.

A pose here is the actor's pose in its own frame (its `<pose>`, the trajectory's origin); the
actors system puts the origin in front of it. Pure arithmetic in floats: the same times give the
same poses, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from simbot.description.actor_scripts import Script, Trajectory
from simbot.transform import Quat, Transform, rpy_to_quaternion

Q = Quat
"""A quaternion x, y, z, w (gz-math holds w first: each sum below is still taken in its order)."""
V = tuple[float, float, float]
EPSILON = 1e-6
"""gz-math's `equal` tolerance."""
CLOSED_TOLERANCE = 1e-3
"""gz-math's `==` of Vector3 and Quaternion (per component): whether a path is closed."""


def _mul(a: Q, b: Q) -> Q:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _inverse(q: Q) -> Q:
    x, y, z, w = q
    s = w * w + x * x + y * y + z * z
    return (0.0, 0.0, 0.0, 1.0) if abs(s) < EPSILON else (-x / s, -y / s, -z / s, w / s)


def _log(q: Q) -> Q:
    x, y, z, w = q
    if abs(w) < 1.0:
        angle = math.acos(w)
        sin = math.sin(angle)
        if abs(sin) >= 1e-3:
            k = angle / sin
            return (k * x, k * y, k * z, 0.0)
    return (x, y, z, 0.0)


def _exp(q: Q) -> Q:
    x, y, z, _ = q
    angle = math.sqrt(x * x + y * y + z * z)
    sin = math.sin(angle)
    k = sin / angle if abs(sin) >= 1e-3 else 1.0
    return (k * x, k * y, k * z, math.cos(angle))


def _slerp(t: float, p: Q, q: Q, shortest: bool) -> Q:
    """gz-math's Quaternion::Slerp, its near-parallel fallback included (written out: it runs every step)."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    cos = pw * qw + px * qx + py * qy + pz * qz
    if cos < 0.0 and shortest:
        cos, qw, qx, qy, qz = -cos, -qw, -qx, -qy, -qz
    if abs(cos) < 1 - 1e-3:
        sin = math.sqrt(1 - cos * cos)
        angle = math.atan2(sin, cos)
        c0, c1 = math.sin((1.0 - t) * angle) / sin, math.sin(t * angle) / sin
        return (c0 * px + c1 * qx, c0 * py + c1 * qy, c0 * pz + c1 * qz, c0 * pw + c1 * qw)
    w, x, y, z = (1.0 - t) * pw + t * qw, (1.0 - t) * px + t * qx, (1.0 - t) * py + t * qy, (1.0 - t) * pz + t * qz
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    return (x / norm, y / norm, z / norm, w / norm)


def _close(a: Sequence[float], b: Sequence[float]) -> bool:
    return all(abs(x - y) <= CLOSED_TOLERANCE for x, y in zip(a, b))


def _position_tangents(points: list[V], tension: float) -> list[V]:
    """gz-math Spline::RecalcTangents."""
    n, k = len(points), 0.5 * (1.0 - tension)
    closed = _close(points[0], points[-1])

    def chord(a: V, b: V) -> V:
        return (k * (b[0] - a[0]), k * (b[1] - a[1]), k * (b[2] - a[2]))

    tangents = [chord(points[i - 1], points[i + 1]) for i in range(1, n - 1)]
    first = chord(points[n - 2], points[1]) if closed else chord(points[0], points[1])
    last = first if closed else chord(points[n - 2], points[n - 1])
    return [first, *tangents, last]


def _rotation_tangents(points: list[Q]) -> list[Q]:
    """gz-math RotationSpline::RecalcTangents."""
    n = len(points)
    closed = _close(points[0], points[-1])
    tangents = []
    for i, p in enumerate(points):
        inverse = _inverse(p)
        after = points[i + 1] if i < n - 1 else (points[1] if closed else p)
        before = points[i - 1] if i > 0 else (points[n - 2] if closed else p)
        a, b = _log(_mul(inverse, after)), _log(_mul(inverse, before))
        tangents.append(_mul(p, _exp((*(-0.25 * (u + v) for u, v in zip(a[:3], b[:3])), 0.0))))  # type: ignore[arg-type]
    return tangents


@dataclass(frozen=True)
class TrajectoryPath:
    """One trajectory's splines, keyed by time from its first waypoint."""

    times: tuple[float, ...]
    points: tuple[V, ...]
    tangents: tuple[V, ...]
    rotations: tuple[Q, ...]
    turns: tuple[Q, ...]
    """The rotation spline's tangents."""
    still: tuple[bool, ...]
    """Per segment: whether its rotation stays one (its ends and their tangents equal)."""

    @staticmethod
    def of(trajectory: Trajectory) -> TrajectoryPath:
        start = trajectory.waypoints[0].time
        points = [w.pose.xyz for w in trajectory.waypoints]
        rotations = [rpy_to_quaternion(w.pose.rpy) for w in trajectory.waypoints]
        many = len(points) > 1
        turns = _rotation_tangents(rotations) if many else rotations
        ends = zip(rotations, rotations[1:], turns, turns[1:])
        return TrajectoryPath(
            tuple(w.time - start for w in trajectory.waypoints),
            tuple(points),
            tuple(_position_tangents(points, trajectory.tension) if many else points),
            tuple(rotations),
            tuple(turns),
            tuple(p == q == a == b for p, q, a, b in ends),
        )

    @property
    def duration(self) -> float:
        return self.times[-1]

    def at(self, time: float) -> tuple[V, Q]:
        """Position and rotation `time` seconds into the trajectory (0 ≤ time ≤ duration)."""
        i, t = self._segment(time)
        if abs(t) < EPSILON:
            return self.points[i], self.rotations[i]
        return self._position(i, t), self._rotation(i, t)

    def _segment(self, time: float) -> tuple[int, float]:
        """gz-common Animation::KeyFramesAtTime: the segment's first waypoint and the time fraction in it."""
        after = next((i for i, at in enumerate(self.times) if at >= time), len(self.times) - 1)
        if after == 0 or time >= self.times[after]:
            return after, 0.0
        t0, t1 = self.times[after - 1], self.times[after]
        return after - 1, (time - t0) / (t1 - t0)

    def _position(self, i: int, t: float) -> V:
        """The cubic Hermite segment from waypoint i (gz-math IntervalCubicSpline)."""
        h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
        p0, p1, m0, m1 = self.points[i], self.points[i + 1], self.tangents[i], self.tangents[i + 1]
        return (
            h00 * p0[0] + h10 * m0[0] + h01 * p1[0] + h11 * m1[0],
            h00 * p0[1] + h10 * m0[1] + h01 * p1[1] + h11 * m1[1],
            h00 * p0[2] + h10 * m0[2] + h01 * p1[2] + h11 * m1[2],
        )

    def _rotation(self, i: int, t: float) -> Q:
        """Squad from waypoint i, the shortest way (gz-math RotationSpline::Interpolate); a segment whose
        ends and tangents are one rotation (walking straight) is that rotation, as squad gives it."""
        if abs(t - 1.0) < EPSILON or self.still[i]:
            return self.rotations[i + 1]
        p, q, a, b = self.rotations[i], self.rotations[i + 1], self.turns[i], self.turns[i + 1]
        return _slerp(2.0 * t * (1.0 - t), _slerp(t, p, q, True), _slerp(t, a, b, False), False)


@dataclass(frozen=True)
class ScriptPath:
    """An actor's script as a function of sim time (see the module docstring)."""

    script: Script
    paths: tuple[TrajectoryPath, ...]

    @staticmethod
    def of(script: Script) -> ScriptPath:
        return ScriptPath(script, tuple(TrajectoryPath.of(t) for t in script.trajectories))

    @property
    def moves(self) -> bool:
        return bool(self.paths)

    def pose_at(self, sim_time: float) -> Transform:
        """The actor in its own frame at `sim_time` seconds of the world's clock."""
        if not self.paths:
            return Transform()
        index, time = self._playing(sim_time)
        position, rotation = self.paths[index].at(time)
        return Transform(position, rotation)

    def trajectory_at(self, sim_time: float) -> int | None:
        """Which trajectory plays at `sim_time` (its index in the script); None without any."""
        return self._playing(sim_time)[0] if self.paths else None

    def _playing(self, sim_time: float) -> tuple[int, float]:
        """The trajectory playing at `sim_time` and the time into it."""
        total = sum(path.duration for path in self.paths)
        time = sim_time - self.script.delay_start if self.script.auto_start else 0.0
        time = max(time, 0.0) + self.script.played
        if not self.script.loop:
            time = min(time, total)
        elif time > total > 0:  # gz-sim subtracts the whole sequence while time exceeds it
            time -= total * (math.ceil(time / total) - 1)
        index = 0
        for index, path in enumerate(self.paths):  # noqa: B007 - the one it stops at plays
            if time <= path.duration:
                break
            time -= path.duration
        return index, time
