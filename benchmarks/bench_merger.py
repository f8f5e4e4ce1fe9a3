"""Benchmark of the lidar merger: one pair of 720-ray scans merged, against bare numpy in the same run.

The scans are the Tug's two lidars in a world of boxes (some rays +inf, as in the warehouse),
decoded from CDR as the merger receives them. Each figure is the median of many calls (one
preemption on a shared machine is not a cost), and a ratio against a baseline timed in the same
run, so it holds where the machine is shared and noisy:

1. the merge of a pair (`ScanMerger.merge`, its rays already worked out for the scans' geometry,
   as for every scan after the first), against the baseline: the least numpy that does the same
   job, written inline — each ray polar → cartesian through the pose, back to polar about
   base_link, `np.minimum.at` into the bins, the two scans' minimum;
2. the same merge with the rays worked out afresh every call (a new geometry: the first scan, or
   a tf change);
3. what the client does per pair beyond that: the merge plus the three LaserScans (`scan`, both
   `*_fixed`) built and encoded to CDR.

Both sides are checked to give the same ranges before anything is timed.

    python benchmarks/bench_merger.py [--repeats N]
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np
import numpy.typing as npt
from tables import publish
from timing import per_call_ms

from simbot.bus import decode, encode, messages
from simbot.scan_merge import Binning, ScanMerger, to_message
from simbot.transform import Transform

TARGET_MS = 2.0
SAMPLES, ANGLE_MAX, RANGE = 720, 1.396263, (0.08, 10.0)
LASER_SCAN = "sensor_msgs/msg/LaserScan"
POSES = {  # the Tug's lidars in base_link (SPEC §1): xyz, yaw
    "base_scan_front": ((0.99, 0.0, 0.17), 0.0),
    "base_scan_back": ((-0.95, 0.0, 0.17), math.pi),
}

Floats = npt.NDArray[np.float64]


def pose(frame: str) -> Floats:
    xyz, yaw = POSES[frame]
    return Transform.of(xyz, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))).matrix()


def scans(seed: int = 0) -> list[tuple[Any, Floats]]:
    """A front and a back scan as they arrive (CDR round trip): walls 2–8 m away, a fifth of the rays +inf."""
    rng = np.random.default_rng(seed)
    pairs = []
    for frame in POSES:
        ranges = np.round(rng.uniform(2.0, 8.0, SAMPLES), 2)
        ranges[rng.random(SAMPLES) < 0.2] = np.inf
        increment = 2 * ANGLE_MAX / (SAMPLES - 1)
        msg = messages.laser_scan(0, frame, (-ANGLE_MAX, ANGLE_MAX, increment), (0.0, 0.2), RANGE, ranges)
        pairs.append((decode(encode(msg), LASER_SCAN), pose(frame)))
    return pairs


def bare_merge(pairs: list[tuple[Any, Floats]], bins: int) -> Floats:
    """The baseline: the same merge in the least numpy, nothing cached."""
    out = np.full(bins, np.inf)
    increment = 2 * math.pi / bins
    for scan, matrix in pairs:
        r = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan.angle_min + scan.angle_increment * np.arange(r.size)
        keep = (r >= scan.range_min) & (r <= scan.range_max)
        r, angles = r[keep], angles[keep]
        x = matrix[0, 3] + r * (matrix[0, 0] * np.cos(angles) + matrix[0, 1] * np.sin(angles))
        y = matrix[1, 3] + r * (matrix[1, 0] * np.cos(angles) + matrix[1, 1] * np.sin(angles))
        index = np.rint((np.arctan2(y, x) + math.pi) / increment).astype(np.intp) % bins
        np.minimum.at(out, index, np.hypot(x, y))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2000, help="calls timed per measurement (median taken)")
    args = parser.parse_args()
    pairs, binning = scans(), Binning()
    merger = ScanMerger(binning)

    _, merged = merger.merge(pairs)
    bare = bare_merge(pairs, binning.bins)
    if not np.array_equal(merged.ranges, bare):
        raise SystemExit(f"the merger and the baseline disagree in {int(np.sum(merged.ranges != bare))} bins")

    def client_pair() -> None:
        alone, both = merger.merge(pairs)
        for rebinned in (*alone, both):
            encode(to_message(rebinned, 0, binning, 0.2))

    baseline = per_call_ms(lambda: bare_merge(pairs, binning.bins), args.repeats)
    cached = per_call_ms(lambda: merger.merge(pairs), args.repeats)
    fresh = per_call_ms(lambda: ScanMerger(binning).merge(pairs), args.repeats)
    whole = per_call_ms(client_pair, args.repeats)
    verdict = "PASS" if cached < TARGET_MS else "NOT REACHED"
    bare_text = f"bare numpy inline, same rays and bins: {baseline:.3f} ms"
    rows = [
        (
            "merge a pair of 720-ray scans (rays cached)",
            f"{cached:.3f} ms = {cached / baseline:.2f}× bare ({verdict})",
            f"< {TARGET_MS:g} ms",
            bare_text,
        ),
        (
            "merge a pair, rays worked out afresh (first scan, tf change)",
            f"{fresh:.3f} ms = {fresh / baseline:.2f}× bare",
            "—",
            bare_text,
        ),
        (
            "per pair in the client: merge + 3 LaserScans built and encoded",
            f"{whole:.3f} ms = {whole / baseline:.2f}× bare",
            "—",
            bare_text,
        ),
    ]
    print(f"\n{SAMPLES}-ray scans into {binning.bins} bins, median of {args.repeats} calls each\n")
    header = ["| measurement | result | target | baseline in the same run |", "| --- | --- | --- | --- |"]
    publish("merger", header + ["| " + " | ".join(row) + " |" for row in rows])


if __name__ == "__main__":
    main()
