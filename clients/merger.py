"""The lidar merger: the front and back scans as one 360° scan in `base_link` (SPEC §5).

Each ray's end point is taken through its sensor's pose in `base_link` (from `tf_static`),
projected onto base_link's plane, and re-binned by its bearing from base_link's origin; a bin
keeps its nearest return, an empty bin reads +inf (REP-117). `lidar_front_fixed` and
`lidar_back_fixed` are each scan alone in the same bins, so `scan` is their elementwise minimum.

The choices, and why:
- Bins: `--bins` (default 1440, 0.25° each) over −π..π; bin i is centred on −π + i·2π/bins, so
  angle_max is π − one bin and bin 0 holds both −π and +π. Slightly coarser than the lidars'
  0.2225° rays: where base_link sees a surface more obliquely than the lidar does, its returns
  spread out, and bins as fine as the rays would leave empty bins between them. A surface the
  lidar itself grazes has rays sparser than any sensible bin, and leaves some empty bins.
- Pairing: StampSync with a slop of half the scan period (each front scan pairs with the
  nearest back one, even from lidars that are not triggered together) and a wait of 0.75 of a
  period: once the next scan of either lidar is in, a partner that has not come is given up and
  the scan is merged alone, one period late. `--scan-period` (default 0.2 s, the lidars' 5 Hz).
- Stamps: `scan` carries the newest stamp of its set, each `*_fixed` its own scan's stamp.
- Limits: a return r of a sensor at distance t from base_link's axis lies between r − t and
  r + t of it, so range_min = max(0, min(range_min − t)) and range_max = max(range_max + t) over
  the scans merged; a consumer that drops readings outside the limits loses none.
- Times: scan_time is the scan period (`--scan-period`): a merged scan comes once per period;
  time_increment 0, as re-binning mixes the rays' order (the simulator casts them at one instant).
- Returns that are +inf, NaN or outside their scan's [range_min, range_max] contribute nothing.

The merge itself (`ScanMerger`) takes LaserScan messages and 4×4 poses and is plain vectorised
numpy, so the benchmark and the tests use it without a bus. Unit vectors of the rays in
base_link are worked out once per scan geometry (frame, angles, ray count, pose) and again only
when one of those changes. Zenoh callbacks only pair scans (StampSync) and queue; the merging and
publishing happen in the client's loop.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.node import RateLimitedWarnings
from simbot.bus.tf_tree import Matrix
from simbot.transform import matmul

from .common import ClockSubscriber, StampedSets, StaticTransforms, client_parser, run_client

logger = logging.getLogger("simbot.merger")

TARGET_FRAME = "base_link"
FIXED_TOPICS = {"lidar_front": "lidar_front_fixed", "lidar_back": "lidar_back_fixed"}
"""Each input scan's topic → the topic of that scan alone in base_link."""
MERGED_TOPIC = "scan"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
DEFAULT_BINS = 1440
DEFAULT_PERIOD_S = 0.2
SLOP_PERIODS = 0.5
MAX_WAIT_PERIODS = 0.75
MAX_GEOMETRIES = 16
POLL_S = 0.1
"""How often the loop looks at the stop flag while no scan comes."""

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


class MergerNode:
    """The merger on the bus: scans paired on Zenoh's threads, merged and published in `spin_once`."""

    def __init__(self, node: Node, binning: Binning, period_s: float) -> None:
        self.merger = ScanMerger(binning)
        self.period_s = period_s
        self.published = 0
        self.alone = 0
        self.rejected = 0
        self._warnings = RateLimitedWarnings()
        self._clock = ClockSubscriber(node)  # says when sim time goes back; the pairing starts afresh by itself
        self._tf = StaticTransforms(node, TARGET_FRAME)
        period_ns = round(period_s * 1e9)
        self._scans = StampedSets(
            node,
            list(FIXED_TOPICS),
            LASER_SCAN,
            round(SLOP_PERIODS * period_ns),
            round(MAX_WAIT_PERIODS * period_ns),
            queue=8,
        )
        self._publishers = {
            topic: node.publisher(topic, messages.LaserScan) for topic in [*FIXED_TOPICS.values(), MERGED_TOPIC]
        }

    @property
    def undecodable(self) -> int:
        """Input payloads that were not LaserScans (dropped by the subscriptions)."""
        return self._scans.undecodable

    def spin_once(self, timeout: float) -> None:
        """Take new transforms, then merge and publish the next set of scans, if one comes within `timeout`."""
        self._tf.refresh()  # the sensors may have moved: their poses (and rays) are looked up again
        ready = self._scans.get(timeout)
        if ready is not None:
            self._publish(ready)

    def _rebin(self, topic: str, scan: Any) -> Rebinned | None:
        """The scan alone in base_link; None, with a warning, when its frame is unknown or its fields are bad."""
        try:
            pose = self._tf.pose(scan.header.frame_id)  # ValueError when tf_static holds a cycle
            if pose is None:
                target = self._tf.target_of(scan.header.frame_id)
                raise BadScan(f"no transform from {scan.header.frame_id!r} to {target!r} on tf_static (yet)")
            return self.merger.rebin(scan, pose)
        except ValueError as exc:  # BadScan included
            self.rejected += 1
            self._warnings.warn(topic, f"scan skipped: {exc}")
            return None

    def _publish(self, ready: Mapping[str, Any]) -> None:
        """Publish each usable scan of a set alone (`*_fixed`), then all of them merged (`scan`)."""
        binning, stamps, alone, frame = self.merger.binning, [], [], TARGET_FRAME
        for topic, scan in ready.items():
            rebinned = self._rebin(topic, scan) if scan is not None else None
            if rebinned is None:
                continue
            stamps.append(messages.stamp_ns(scan.header))
            alone.append(rebinned)
            frame = self._tf.target_of(scan.header.frame_id)
            message = to_message(rebinned, stamps[-1], binning, self.period_s, frame)
            self._publishers[FIXED_TOPICS[topic]].put(message)
        if not alone:
            return
        self._publishers[MERGED_TOPIC].put(to_message(combine(alone), max(stamps), binning, self.period_s, frame))
        self.published += 1
        if len(alone) < len(FIXED_TOPICS):
            self.alone += 1

    def summary(self) -> str:
        return (
            f"published {self.published} merged scans ({self.alone} from one lidar alone); "
            f"dropped {self.undecodable} undecodable payloads, skipped {self.rejected} scans; "
            f"sim time went back {self._clock.watch.jumps} times"
        )


def _body(args: argparse.Namespace, node: Node, stop: threading.Event) -> int:
    merger = MergerNode(node, Binning(args.bins), args.scan_period)
    logger.info("merging lidar_front and lidar_back into %s in %s (%d bins)", MERGED_TOPIC, TARGET_FRAME, args.bins)
    while not stop.is_set():
        merger.spin_once(POLL_S)
    logger.info("%s", merger.summary())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot merger`: lidar_front + lidar_back → scan (and *_fixed) in base_link."""
    parser = client_parser("simbot merger", "Merge the front and back lidar scans into one 360° scan in base_link.")
    parser.add_argument(
        "--bins",
        type=number(int),
        default=DEFAULT_BINS,
        help=f"bins over the full circle (default {DEFAULT_BINS}, 0.25° each)",
    )
    parser.add_argument(
        "--scan-period",
        type=number(float),
        default=DEFAULT_PERIOD_S,
        metavar="SECONDS",
        help=f"the lidars' scan period (default {DEFAULT_PERIOD_S}); scans pair within half of it",
    )
    return run_client(parser, argv, _body)


if __name__ == "__main__":
    sys.exit(main())
