"""Two planar scans as one: LaserScans re-binned by bearing around a target frame's origin.

The library's half of the lidar merger (`simbot merger`, clients/merger.py, SPEC §5) and of the
gym's scan observation (simbot/gym/observe.py): both merge the front and back scans this way, so
the rule lives here once. Each ray's end point is taken through its sensor's pose in the target
frame (`base_link`), projected onto the target's plane, and re-binned by its bearing from the
target's origin; a bin keeps its nearest return, an empty bin reads +inf (REP-117).

- Bins (`Binning`): N over −π..π, bin i centred on −π + i·2π/N, so angle_max is π − one bin and
  bin 0 holds both −π and +π. The merger's default, 1440 (0.25° each), is slightly coarser than
  the tug's 0.2225° rays: where base_link sees a surface more obliquely than the lidar does, its
  returns spread out, and bins as fine as the rays would leave empty bins between them.
- Limits: a return r of a sensor at distance t from the target's axis lies between r − t and
  r + t of it, so range_min = max(0, min(range_min − t)) and range_max = max(range_max + t) over
  the scans merged; a consumer that drops readings outside the limits loses none.
- Returns that are +inf, NaN or outside their scan's [range_min, range_max] contribute nothing.

`ScanMerger` takes LaserScan messages and 4×4 poses and is plain vectorised numpy, with no bus.
The unit vectors of the rays in the target plane are worked out once per scan geometry (frame,
angles, ray count, pose) and again only when one of those changes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.bus.tf_tree import Matrix
from simbot.transform import matmul

TARGET_FRAME = "base_link"
DEFAULT_BINS = 1440
MAX_GEOMETRIES = 16
"""Scan geometries a merger keeps (a scan whose angles keep changing must not grow it without bound)."""

Floats = npt.NDArray[np.float64]


class BadScan(ValueError):
    """A LaserScan whose fields contradict each other (ray count vs angles, non-finite angles)."""


@dataclass(frozen=True)
class Binning:
    """N bins over the full circle, bin i centred on −π + i·2π/N (LaserScan's angle_min + i·increment)."""

    bins: int = DEFAULT_BINS

    def __post_init__(self) -> None:
        if self.bins < 1:
            raise ValueError(f"bins must be ≥ 1, not {self.bins}")

    @property
    def angle_min(self) -> float:
        return -math.pi

    @property
    def increment(self) -> float:
        return 2 * math.pi / self.bins

    @property
    def angle_max(self) -> float:
        return self.angle_min + (self.bins - 1) * self.increment


@dataclass(frozen=True)
class Rebinned:
    """One scan in the target frame's bins, with the distances its returns can have from the origin."""

    ranges: Floats
    range_min: float
    range_max: float


@dataclass(frozen=True)
class _Geometry:
    """What depends only on a scan's frame, angles and pose: its rays in the target plane."""

    pose: Matrix
    origin: Floats  # (2,) the sensor in the target plane
    directions: Floats  # (2, n) each ray's unit direction, projected onto the target plane
    offset: float  # the sensor's distance from the target frame's z axis


def ray_angles(scan: Any) -> Floats:
    """The angle of each ray (angle_min + i·increment); BadScan when the fields disagree."""
    count = len(scan.ranges)
    start, end, step = float(scan.angle_min), float(scan.angle_max), float(scan.angle_increment)
    if not all(math.isfinite(v) for v in (start, end, step)):
        raise BadScan(f"angles not finite: min {start}, max {end}, increment {step}")
    if count > 1 and abs(start + (count - 1) * step - end) > abs(step) / 2 + 1e-6:
        raise BadScan(f"{count} rays from {start:.6f} by {step:.6f} rad do not end at angle_max {end:.6f}")
    return start + step * np.arange(count, dtype=np.float64)


class ScanMerger:
    """LaserScans + their sensors' poses (4×4, sensor → target frame) → ranges in `binning`'s bins."""

    def __init__(self, binning: Binning = Binning()) -> None:
        self.binning = binning
        self._geometries: dict[tuple[str, float, float, float, int], _Geometry] = {}

    def _geometry(self, scan: Any, pose: Matrix) -> _Geometry:
        """The scan's rays in the target plane, worked out again only when its angles or pose change."""
        key = (
            scan.header.frame_id,
            float(scan.angle_min),
            float(scan.angle_max),
            float(scan.angle_increment),
            len(scan.ranges),
        )
        cached = self._geometries.get(key)
        if cached is not None and np.array_equal(cached.pose, pose):
            return cached
        if len(self._geometries) >= MAX_GEOMETRIES:
            self._geometries.clear()  # scans of ever-changing angles must not grow the cache without bound
        angles = ray_angles(scan)
        in_sensor = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
        origin = np.array(pose[:2, 3], dtype=np.float64)
        geometry = _Geometry(
            np.array(pose, dtype=np.float64), origin, matmul(pose[:2, :3], in_sensor), float(np.hypot(*origin))
        )
        self._geometries[key] = geometry
        return geometry

    def rebin(self, scan: Any, pose: Matrix) -> Rebinned:
        """The nearest return per bin of one scan seen from the target frame's origin; +inf where none."""
        geometry = self._geometry(scan, pose)
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        low, high = float(scan.range_min), float(scan.range_max)
        valid = (ranges >= low) & (ranges <= high)  # false for NaN and inf too
        r = ranges[valid]
        x = geometry.origin[0] + r * geometry.directions[0, valid]
        y = geometry.origin[1] + r * geometry.directions[1, valid]
        binning = self.binning
        index = np.rint((np.arctan2(y, x) - binning.angle_min) / binning.increment).astype(np.intp)
        index %= binning.bins  # +π is the same bin as −π
        out = np.full(binning.bins, np.inf)
        np.minimum.at(out, index, np.hypot(x, y))
        return Rebinned(out, max(0.0, low - geometry.offset), high + geometry.offset)

    def merge(self, scans: Sequence[tuple[Any, Matrix]]) -> tuple[list[Rebinned], Rebinned]:
        """Each scan rebinned alone, and all of them merged."""
        alone = [self.rebin(scan, pose) for scan, pose in scans]
        return alone, combine(alone)


def combine(alone: Sequence[Rebinned]) -> Rebinned:
    """Scans in the same bins as one: the nearest return per bin is the nearest of their nearest."""
    if not alone:
        raise ValueError("combine needs at least one scan")
    return Rebinned(
        np.minimum.reduce([a.ranges for a in alone]),
        min(a.range_min for a in alone),
        max(a.range_max for a in alone),
    )


def to_message(rebinned: Rebinned, ns: int, binning: Binning, scan_time: float, frame: str = TARGET_FRAME) -> Any:
    """A sensor_msgs/LaserScan in the target frame (`tug_2/base_link` for a robot in namespace tug_2)."""
    return messages.laser_scan(
        ns,
        frame,
        (binning.angle_min, binning.angle_max, binning.increment),
        (0.0, scan_time),
        (rebinned.range_min, rebinned.range_max),
        rebinned.ranges,
    )
