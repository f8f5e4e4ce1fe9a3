"""Planar lidar (SDF `gpu_lidar`, `lidar`, `ray`, `gpu_ray`): one PyBullet ray batch per scan.

Every ray of a scan is cast at the same sim instant from the sensor's world pose, starting at
range_min so nothing inside the housing is seen. The robot carrying the lidar is invisible to
its rays (physics.blind_rays_to), as a real lidar's own chassis is below or behind its window;
every other robot is seen.
A ray that hits nothing reads +inf (REP-117); a hit reads its range with the SDF's gaussian
noise, quantised to the range resolution and kept within [range_min, range_max].
`time_increment` is 0 because the rays really are simultaneous: a consumer that de-skews by it
would otherwise move points that did not move.

SDF parameters (under `<lidar>`, or `<ray>` in SDF before 1.7; `LidarParams`):

| element | default | meaning |
| --- | --- | --- |
| `<scan><horizontal><samples>` | 1 | rays per scan (at least 1) |
| `<scan><horizontal><min_angle>`, `<max_angle>` | 0, 0 | first and last ray, radians |
| `<scan><vertical><samples>`, `<min_angle>`, `<max_angle>` | 1, 0, 0 | a LaserScan holds one plane: the middle one is cast |
| `<range><min>`, `<range><max>` | required | rays start at min; no hit within max reads +inf |
| `<range><resolution>` | 0 | ranges are quantised to it (0: not quantised) |
| `<noise>` (`type`, `mean`, `stddev`) | none | gaussian noise per ray |
| `<update_rate>` (of the `<sensor>`) | the physics rate | scans per second |
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.rotations import quaternion_to_matrix
from simbot.sim.sensor_params import Noise, SdfElement
from simbot.sim.system import (
    Sampled,
    SystemConfigError,
    SystemContext,
    UpdateInfo,
    sensor_frame,
    sensor_rate,
    sensor_topic,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ScanAxis:
    samples: int = 1
    min_angle: float = 0.0
    max_angle: float = 0.0

    @staticmethod
    def from_sdf(element: SdfElement) -> ScanAxis:
        return ScanAxis(
            element.integer("samples", 1), element.number("min_angle", 0.0), element.number("max_angle", 0.0)
        )


@dataclass(frozen=True)
class LidarParams:
    """A lidar's SDF parameters (the table in the module docstring)."""

    horizontal: ScanAxis
    vertical: ScanAxis
    range_min: float
    range_max: float
    range_resolution: float = 0.0
    noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> LidarParams:
        root = SdfElement.of(sensor)
        element = root.child("lidar") or root.child("ray")
        if element is None:
            raise SystemConfigError(f"sensor {sensor.name}: type {sensor.type!r} needs a <lidar> or <ray> element")
        scan = element.require("scan")
        ranges = element.require("range")
        params = LidarParams(
            horizontal=ScanAxis.from_sdf(scan.require("horizontal")),
            vertical=ScanAxis.from_sdf(scan.child_or_empty("vertical")),
            range_min=ranges.required_number("min"),
            range_max=ranges.required_number("max"),
            range_resolution=ranges.number("resolution", 0.0),
            noise=(element.noise() or Noise()).applied,
        )
        _check(sensor.name, params)
        return params


def ray_directions(spec: LidarParams) -> tuple[npt.NDArray[np.float64], float]:
    """Unit vectors of every ray in the sensor frame (x forward, z up), and the angle increment."""
    h = spec.horizontal
    angles = np.linspace(h.min_angle, h.max_angle, h.samples)
    increment = (h.max_angle - h.min_angle) / (h.samples - 1) if h.samples > 1 else 0.0
    elevation = (
        spec.vertical.min_angle
        if spec.vertical.samples <= 1
        else (spec.vertical.min_angle + spec.vertical.max_angle) / 2
    )
    cos_e = math.cos(elevation)
    directions = np.stack(
        [np.cos(angles) * cos_e, np.sin(angles) * cos_e, np.full_like(angles, math.sin(elevation))], axis=1
    )
    return directions, increment


def _check(name: str, spec: LidarParams) -> None:
    if spec.horizontal.samples < 1:
        raise SystemConfigError(
            f"sensor {name}: <horizontal><samples> must be at least 1, got {spec.horizontal.samples}"
        )
    if not 0 <= spec.range_min < spec.range_max or not math.isfinite(spec.range_max):
        raise SystemConfigError(
            f"sensor {name}: <range> needs 0 ≤ min < max, got min {spec.range_min} max {spec.range_max}"
        )
    if spec.vertical.samples > 1:
        log.warning(
            "sensor %s: %d vertical samples; a LaserScan holds one plane, the middle one is published",
            name,
            spec.vertical.samples,
        )


class Lidar(Sampled):
    """sensor_msgs/LaserScan at the sensor's rate, stamped with the sim time the rays were cast."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = LidarParams.from_sdf(sensor)
        rate = sensor_rate(sensor, 1.0 / ctx.physics.step_size)
        super().__init__(sensor.name, rate)
        self._model, self._link, self._pose = model, link.name, sensor.pose
        self._physics = ctx.physics
        self._physics.blind_rays_to(model)
        self._rng = ctx.rng
        self._directions, increment = ray_directions(self.params)
        h = self.params.horizontal
        self._frame = sensor_frame(sensor)
        self._angles = (h.min_angle, h.max_angle, increment)
        self._times = (0.0, 1.0 / rate)
        self._pub = ctx.bus.publisher(sensor_topic(sensor), messages.LaserScan)

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self.due(info):
            return
        spec = self.params
        self._pub.put(
            messages.laser_scan(
                now_ns, self._frame, self._angles, self._times, (spec.range_min, spec.range_max), self.scan()
            )
        )
        self.published(now_ns)

    def scan(self) -> npt.NDArray[np.float64]:
        """The ranges the lidar reads now: true distances, noise, quantisation, +inf for no return."""
        spec = self.params
        position, quat = self._physics.frame_pose(self._model, self._link, self._pose)
        directions = self._directions @ quaternion_to_matrix(quat).T
        origin = np.asarray(position)
        fractions = self._physics.cast_rays(
            origin + directions * spec.range_min, origin + directions * spec.range_max, blind_to=self._model
        )
        ranges = spec.range_min + fractions * (spec.range_max - spec.range_min)
        return self._measured(ranges)

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
