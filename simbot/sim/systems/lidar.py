"""Lidar, planar or 3-D (SDF `gpu_lidar`, `lidar`, `ray`, `gpu_ray`): every lidar due in a step cast together.

Every ray of a scan (horizontal × vertical samples) is cast at the same sim instant from the
sensor's world pose, starting at range_min so nothing inside the housing is seen, against the
collision geometry (physics.cast_ray_batches: the ray engine, else PyBullet's rayTestBatch). The robot
carrying the lidar is invisible to its rays (physics.blind_rays_to), as a real lidar's own chassis
is below or behind its window; every other robot is seen.
A ray that hits nothing reads +inf (REP-117); a hit reads its range with the SDF's gaussian
noise, quantised to the range resolution and kept within [range_min, range_max].
`time_increment` is 0 because the rays really are simultaneous: a consumer that de-skews by it
would otherwise move points that did not move. The key is `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/scan`.

Two outputs, as Gazebo's lidars give them: sensor_msgs/LaserScan on the topic, one plane: the
middle of the vertical fan, (min_angle + max_angle)/2, which is a row of the fan when the vertical
samples are odd and one more row of rays when they are even; and sensor_msgs/PointCloud2 on
`<topic>/points`, organised as Gazebo packs it: a row per vertical angle from min_angle up (its
`ring`), a column per horizontal angle, fields x y z intensity (float32) and ring (uint16), 18
bytes a point, in the sensor frame; NaN coordinates where a ray returned nothing, intensity 0
(simbot models no retro-reflectance). The cloud is built only while someone subscribes to it;
the rays and their noise are the same either way, so a subscriber never changes the scan.

SDF parameters (under `<lidar>`, or `<ray>` in SDF before 1.7; `LidarParams`, simbot/description/lidar_params.py):

| element | default | meaning |
| --- | --- | --- |
| `<scan><horizontal><samples>` | 1 | rays per scan (at least 1) |
| `<scan><horizontal><min_angle>`, `<max_angle>` | 0, 0 | first and last ray, radians |
| `<scan><vertical><samples>`, `<min_angle>`, `<max_angle>` | 1, 0, 0 | rows of the 3-D fan (1: planar, at min_angle) |
| `<range><min>`, `<range><max>` | required | rays start at min; no hit within max reads +inf |
| `<range><resolution>` | 0 | ranges are quantised to it (0: not quantised) |
| `<noise>` (`type`, `mean`, `stddev`) | none | gaussian noise per ray |
| `<update_rate>` (of the `<sensor>`) | the physics rate | scans per second |
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.lidar_params import LidarParams
from simbot.description.naming import sensor_frame, sensor_rate
from simbot.description.sensor_params import Noise
from simbot.sim.kit.rates import Sampled
from simbot.sim.loop.system import Batch, SystemContext, UpdateInfo
from simbot.sim.physics.protocols import RayBatch
from simbot.transform import matmul, quaternion_to_matrix


@dataclass(frozen=True)
class Fan:
    """The rays of one scan: unit directions (rows × horizontal × 3, sensor frame: x forward, z up),
    how many leading rows the cloud holds, the row the LaserScan reads, and its angle increment."""

    directions: npt.NDArray[np.float64]
    cloud_rows: int
    scan_row: int
    increment: float


def ray_fan(spec: LidarParams) -> Fan:
    """Every ray of a scan: the vertical rows, and the middle plane as an extra row where no row is it."""
    h, v = spec.horizontal, spec.vertical
    azimuths = np.linspace(h.min_angle, h.max_angle, h.samples)
    increment = (h.max_angle - h.min_angle) / (h.samples - 1) if h.samples > 1 else 0.0
    elevations = np.linspace(v.min_angle, v.max_angle, v.samples) if v.samples > 1 else np.array([v.min_angle])
    scan_row = elevations.size // 2
    if elevations.size % 2 == 0:  # no middle row: the LaserScan's plane is cast as one more
        elevations, scan_row = np.append(elevations, (v.min_angle + v.max_angle) / 2), elevations.size
    cos_e, sin_e = np.cos(elevations)[:, None], np.sin(elevations)[:, None]
    directions = np.stack(
        [cos_e * np.cos(azimuths), cos_e * np.sin(azimuths), np.broadcast_to(sin_e, (elevations.size, h.samples))],
        axis=2,
    )
    return Fan(directions, max(v.samples, 1), scan_row, increment)


class Lidar(Sampled):
    """sensor_msgs/LaserScan, and the cloud on `/points`, at the sensor's rate, stamped with the sim
    time the rays were cast."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = LidarParams.from_sdf(sensor)
        rate = sensor_rate(sensor, 1.0 / ctx.physics.step_size)
        super().__init__(sensor.name, rate)
        self._where = (model, link.name, sensor.pose)
        self._physics = ctx.physics
        self._physics.blind_rays_to(model)
        self._rng = ctx.rng
        self._fan = ray_fan(self.params)
        h = self.params.horizontal
        self._frame = ctx.bus.frame(sensor_frame(sensor))
        self._angles = (h.min_angle, h.max_angle, self._fan.increment)
        self._times = (0.0, 1.0 / rate)
        topic = ctx.sensor_topic("scan")
        self._pub = ctx.bus.publisher(topic, messages.LaserScan)
        self._points = ctx.bus.publisher(f"{topic}/points", messages.PointCloud2)

    def post_update(self, info: UpdateInfo) -> None:
        if self.next_due_ns <= info.sim_time_ns:
            type(self).post_update_all([Batch([self], info)])

    @classmethod
    def post_update_all(cls, batches: Sequence[Batch]) -> None:
        """Every lidar handed (each due now: the loop hands a paced class no other) scans. Those
        someone subscribes to cast their rays together, in one cast of their world, their frames
        read in one query; the others only draw their noise, so that what a subscriber gets does
        not depend on who listened before."""
        for lidars, info in batches:
            Lidar._scan_world(lidars, info)

    @staticmethod
    def _scan_world(lidars: Sequence[Lidar], info: UpdateInfo) -> None:
        """A world's lidars due now scan (see `post_update_all`)."""
        Sampled.sampled_all(lidars, [info.sim_time_ns] * len(lidars))
        watched = []
        for lidar in lidars:
            if lidar._pub.has_subscribers or lidar._points.has_subscribers:
                watched.append(lidar)
            else:
                _noise(lidar.params.noise, lidar._rng, (lidar._fan.directions[..., 0].size,))
        if watched:
            physics = watched[0]._physics
            frames = physics.frame_motions([lidar._where for lidar in watched])
            rays = [
                lidar._rays(position, quat)
                for lidar, position, quat in zip(watched, frames.positions, frames.orientations)
            ]
            for lidar, fractions in zip(watched, physics.cast_ray_batches(rays)):
                lidar._publish(info.sim_time_ns, lidar._ranges(fractions))

    def _publish(self, now_ns: int, ranges: npt.NDArray[np.float64]) -> None:
        spec, fan = self.params, self._fan
        scan_ranges = ranges[fan.scan_row]
        self._pub.put(
            messages.laser_scan(
                now_ns, self._frame, self._angles, self._times, (spec.range_min, spec.range_max), scan_ranges
            )
        )
        if self._points.has_subscribers:
            returned = np.where(np.isfinite(ranges[: fan.cloud_rows]), ranges[: fan.cloud_rows], np.nan)
            self._points.put(
                messages.lidar_points(now_ns, self._frame, returned[:, :, None] * fan.directions[: fan.cloud_rows])
            )

    def scan(self) -> npt.NDArray[np.float64]:
        """The ranges the lidar reads now, a row per ray row of the fan: true distances, noise,
        quantisation, +inf for no return."""
        rays = self._rays(*self._physics.frame_pose(*self._where))
        return self._ranges(self._physics.cast_ray_batches([rays])[0])

    def _rays(self, position: npt.ArrayLike, quat: Sequence[float]) -> RayBatch:
        """The scan's rays from the sensor's pose: range_min to range_max along each direction, blind to its robot."""
        spec = self.params
        directions = matmul(self._fan.directions.reshape(-1, 3), quaternion_to_matrix(quat).T)
        origin = np.asarray(position, dtype=float)
        return origin + directions * spec.range_min, origin + directions * spec.range_max, self._where[0]

    def _ranges(self, fractions: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The measured ranges of the cast's fractions, shaped as the fan."""
        spec = self.params
        ranges = spec.range_min + fractions * (spec.range_max - spec.range_min)
        return self._measured(ranges).reshape(self._fan.directions.shape[:2])

    def _measured(self, ranges: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        spec = self.params
        hit = np.isfinite(ranges)
        noisy = ranges + _noise(spec.noise, self._rng, ranges.shape)
        if spec.range_resolution > 0:
            noisy = np.round(noisy / spec.range_resolution) * spec.range_resolution
        return np.where(hit, np.clip(noisy, spec.range_min, spec.range_max), np.inf)


def _noise(noise: Noise, rng: np.random.Generator, shape: tuple[int, ...]) -> npt.NDArray[np.float64] | float:
    """SDF gaussian noise (mean, stddev) per ray; nothing drawn where there is none."""
    if noise.stddev == 0 and noise.mean == 0:
        return 0.0
    return rng.normal(noise.mean, noise.stddev, shape)
