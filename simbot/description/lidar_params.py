"""A lidar's parameters (SDF `gpu_lidar`, `lidar`, `ray`, `gpu_ray`), which the lidar system and the
gym (how far a robot's lidars reach) both read. The table of them, and what the lidar does with
them: simbot/sim/systems/lidar.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from simbot.description.errors import SystemConfigError
from simbot.description.model import Sensor
from simbot.description.sensor_params import Noise, SdfElement

LIDAR_TYPES = ("gpu_lidar", "lidar", "ray", "gpu_ray")
"""The SDF sensor types of a lidar: Gazebo's GPU and CPU ones, and SDF's older name (simbot's
`simbot.sensors` entry points give each to the lidar system)."""


@dataclass(frozen=True)
class ScanAxis:
    """The rays of one axis of a scan: how many, from which angle to which (radians)."""

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
    """A lidar's SDF parameters (the table in simbot/sim/systems/lidar.py), checked."""

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


def _check(name: str, spec: LidarParams) -> None:
    """SystemConfigError naming the sensor and the element for a scan that cannot be cast."""
    if spec.horizontal.samples < 1:
        raise SystemConfigError(
            f"sensor {name}: <horizontal><samples> must be at least 1, got {spec.horizontal.samples}"
        )
    if not 0 <= spec.range_min < spec.range_max or not math.isfinite(spec.range_max):
        raise SystemConfigError(
            f"sensor {name}: <range> needs 0 ≤ min < max, got min {spec.range_min} max {spec.range_max}"
        )
    if spec.vertical.samples < 1:
        raise SystemConfigError(f"sensor {name}: <vertical><samples> must be at least 1, got {spec.vertical.samples}")
