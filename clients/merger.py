"""The lidar merger: the front and back scans as one 360° scan in `base_link` (SPEC §5).

The merge itself (bins, limits, which returns count) is the library's `simbot.scan_merge`, which
the gym's scan observation shares; this program pairs the scans on the bus and publishes them.
`lidar_front_fixed` and `lidar_back_fixed` are each scan alone in the same bins, so `scan` is
their elementwise minimum.

The choices, and why:
- Bins: `--bins` (default 1440, 0.25° each) over −π..π (`simbot.scan_merge.Binning`).
- Pairing: StampSync with a slop of half the scan period (each front scan pairs with the
  nearest back one, even from lidars that are not triggered together) and a wait of 0.75 of a
  period: once the next scan of either lidar is in, a partner that has not come is given up and
  the scan is merged alone, one period late. `--scan-period` (default 0.2 s, the lidars' 5 Hz).
- Stamps: `scan` carries the newest stamp of its set, each `*_fixed` its own scan's stamp.
- Times: scan_time is the scan period (`--scan-period`): a merged scan comes once per period;
  time_increment 0, as re-binning mixes the rays' order (the simulator casts them at one instant).

Zenoh callbacks only pair scans (StampSync) and queue; the merging and publishing happen in the
client's loop.
"""

from __future__ import annotations

import logging
import sys
import threading
from collections.abc import Mapping, Sequence
from typing import Any

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.node import RateLimitedWarnings
from simbot.scan_merge import DEFAULT_BINS, TARGET_FRAME, BadScan, Binning, Rebinned, ScanMerger, combine, to_message

from .common import ClockSubscriber, StampedSets, StaticTransforms, client_parser, run_client

logger = logging.getLogger("simbot.merger")

FIXED_TOPICS = {"lidar_front": "lidar_front_fixed", "lidar_back": "lidar_back_fixed"}
"""Each input scan's topic → the topic of that scan alone in base_link."""
MERGED_TOPIC = "scan"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
DEFAULT_PERIOD_S = 0.2
SLOP_PERIODS = 0.5
MAX_WAIT_PERIODS = 0.75
POLL_S = 0.1
"""How often the loop looks at the stop flag while no scan comes."""


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


def run(node: Node, stop: threading.Event, bins: int, scan_period_s: float) -> int:
    """Merges the lidars' scans into `bins` bins until `stop`, pairing scans within half of `scan_period_s`."""
    merger = MergerNode(node, Binning(bins), scan_period_s)
    logger.info("merging lidar_front and lidar_back into %s in %s (%d bins)", MERGED_TOPIC, TARGET_FRAME, bins)
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
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, args.bins, args.scan_period))


if __name__ == "__main__":
    sys.exit(main())
