"""Planar lidar (SDF `gpu_lidar`, `lidar`, `ray`, `gpu_ray`): one PyBullet ray batch per scan.

Every ray of a scan is cast at the same sim instant from the sensor's world pose, starting at
range_min so nothing inside the housing is seen. The robot carrying the lidar is invisible to
its rays (physics.blind_rays_to), as a real lidar's own chassis is below or behind its window.
A ray that hits nothing reads +inf (REP-117); a hit reads its range with the SDF's gaussian
noise, quantised to the range resolution and kept within [range_min, range_max].
`time_increment` is 0 because the rays really are simultaneous: a consumer that de-skews by it
would otherwise move points that did not move.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Lidar as LidarSpec
from simbot.description.model import Noise
from simbot.rotations import quaternion_to_matrix
from simbot.sim.system import (
    Sampled,
    SystemConfigError,
    SystemContext,
    applied_noise,
    sensor_frame,
    sensor_rate,
    sensor_topic,
)

log = logging.getLogger(__name__)


def ray_directions(spec: LidarSpec) -> tuple[npt.NDArray[np.float64], float]:
    """Unit vectors of every ray in the sensor frame (x forward, z up), and the angle increment."""
    h = spec.horizontal
    angles = np.linspace(h.min_angle, h.max_angle, h.samples)
    increment = (h.max_angle - h.min_angle) / (h.samples - 1) if h.samples > 1 else 0.0
    elevation = spec.vertical.min_angle if spec.vertical.samples <= 1 else (spec.vertical.min_angle + spec.vertical.max_angle) / 2
    cos_e = math.cos(elevation)
    directions = np.stack([np.cos(angles) * cos_e, np.sin(angles) * cos_e, np.full_like(angles, math.sin(elevation))], axis=1)
    return directions, increment


def _check(name: str, spec: LidarSpec) -> None:
    if spec.horizontal.samples < 1:
        raise SystemConfigError(f"sensor {name}: <horizontal><samples> must be at least 1, got {spec.horizontal.samples}")
    if not 0 <= spec.range_min < spec.range_max or not math.isfinite(spec.range_max):
        raise SystemConfigError(f"sensor {name}: <range> needs 0 ≤ min < max, got min {spec.range_min} max {spec.range_max}")
    if spec.vertical.samples > 1:
        log.warning("sensor %s: %d vertical samples; a LaserScan holds one plane, the middle one is published", name, spec.vertical.samples)


class Lidar(Sampled):
    """sensor_msgs/LaserScan at the sensor's rate, stamped with the sim time the rays were cast."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        if sensor.lidar is None:
            raise SystemConfigError(f"sensor {sensor.name}: type {sensor.type!r} needs a <lidar> or <ray> element")
        _check(sensor.name, sensor.lidar)
        rate = sensor_rate(sensor, 1.0 / ctx.physics.step_size)
        super().__init__(sensor.name, rate)
        self._spec = sensor.lidar
        self._model, self._link, self._pose = model, link.name, sensor.pose
        self._physics = ctx.physics
        self._physics.blind_rays_to(model)
        self._rng = ctx.rng
        self._directions, increment = ray_directions(sensor.lidar)
        h = sensor.lidar.horizontal
        self._frame = sensor_frame(sensor)
        self._angles = (h.min_angle, h.max_angle, increment)
        self._times = (0.0, 1.0 / rate)
        self._pub = ctx.bus.publisher(sensor_topic(sensor), messages.LaserScan)

    def post_update(self, now_ns: int) -> None:
        if not self.due(now_ns):
            return
        spec = self._spec
        self._pub.put(
            messages.laser_scan(now_ns, self._frame, self._angles, self._times, (spec.range_min, spec.range_max), self.scan())
        )
        self.published(now_ns)

    def scan(self) -> npt.NDArray[np.float64]:
        """The ranges the lidar reads now: true distances, noise, quantisation, +inf for no return."""
        spec = self._spec
        position, quat = self._physics.frame_pose(self._model, self._link, self._pose)
        directions = self._directions @ quaternion_to_matrix(quat).T
        origin = np.asarray(position)
        fractions = self._physics.cast_rays(origin + directions * spec.range_min, origin + directions * spec.range_max)
        ranges = spec.range_min + fractions * (spec.range_max - spec.range_min)
        return self._measured(ranges)

    def _measured(self, ranges: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        spec = self._spec
        hit = np.isfinite(ranges)
        noisy = ranges + _noise(spec.noise, self._rng, ranges.shape)
        if spec.range_resolution > 0:
            noisy = np.round(noisy / spec.range_resolution) * spec.range_resolution
        return np.where(hit, np.clip(noisy, spec.range_min, spec.range_max), np.inf)


def _noise(sdf_noise: Noise | None, rng: np.random.Generator, shape: tuple[int, ...]) -> npt.NDArray[np.float64] | float:
    """SDF gaussian noise (mean, stddev) per ray; nothing drawn where there is none."""
    noise = applied_noise(sdf_noise)
    if noise.stddev == 0 and noise.mean == 0:
        return 0.0
    return rng.normal(noise.mean, noise.stddev, shape)
