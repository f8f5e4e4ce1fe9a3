"""Benchmark of the CDR encoding of the messages the server publishes at high rates: `encode` (whose
fixed-layout writers, simbot/bus/fixed_cdr.py, write Imu, Odometry, TFMessage, Clock and LaserScan)
against rosbags' generic serializer, the baseline, timed on the same messages in the same run.

The messages are a tug's, built by the constructors its systems use and named under its namespace
(`tug_12/…`): the IMU's, the drive's odometry and its one-transform tf, the joints' tf, the clock,
and a 720-ray scan (a fifth of the rays +inf). Both sides are checked to give the same bytes before
anything is timed. Each figure is the median over many batches of calls (one preemption on a
shared machine is not a cost), divided by the batch.

    python benchmarks/bench_codec.py [--repeats N]
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from tables import publish
from timing import per_call_ms

from simbot.bus import encode, messages
from simbot.bus.codec import TYPESTORE
from simbot.bus.frames import with_frame_prefix

BATCH = 100
NS = 1_234_567_890_123
QUAT = (0.0, 0.0, math.sin(0.4), math.cos(0.4))
WHEELS = ("front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel")


def tug_messages() -> dict[str, Any]:
    """What one tug publishes, by row name, as its systems build it and under its namespace."""
    rng = np.random.default_rng(0)
    ranges = rng.uniform(0.5, 10.0, 720)
    ranges[rng.random(720) < 0.2] = np.inf
    odom = messages.transform_stamped(NS, "odom", "base_footprint", (3.0, -1.5, 0.0), QUAT)
    built = {
        "sensor_msgs/Imu": messages.imu(
            NS, "imu_link", QUAT, (0.01, -0.02, 0.3), (0.1, 0.0, 9.81), ((1e-4,) * 9, (2e-4,) * 9, (3e-4,) * 9)
        ),
        "nav_msgs/Odometry": messages.odometry(
            NS, "odom", "base_footprint", (3.0, -1.5, 0.0), QUAT, (0.8, 0.0, 0.0), (0.0, 0.0, 0.3), [1e-3] * 36
        ),
        "tf2_msgs/TFMessage, 1 transform (the drive's)": messages.tf_message([odom]),
        "tf2_msgs/TFMessage, 4 transforms (the wheels')": messages.tf_message(
            messages.transform_stamped(NS, "base_link", f"{wheel}_link", (0.5, 0.3, 0.1), QUAT) for wheel in WHEELS
        ),
        "rosgraph_msgs/Clock": messages.clock(NS),
        "sensor_msgs/LaserScan, 720 rays": messages.laser_scan(
            NS, "base_scan_front", (-math.pi / 2, math.pi / 2, math.pi / 719), (0.0, 0.1), (0.08, 10.0), ranges
        ),
    }
    return {name: with_frame_prefix(msg, "tug_12") for name, msg in built.items()}


def rosbags(msg: Any) -> bytes:
    """The baseline: rosbags' serializer, as the codec called it for every message before."""
    return bytes(TYPESTORE.serialize_cdr(msg, msg.__msgtype__, little_endian=True))


def per_message_us(write: Callable[[Any], bytes], msg: Any, repeats: int) -> float:
    """Median µs of one message, timed in batches (a single call is too short for the clock's overhead)."""

    def batch() -> None:
        for _ in range(BATCH):
            write(msg)

    return per_call_ms(batch, repeats) * 1e3 / BATCH


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=300, help=f"batches of {BATCH} calls timed (median taken)")
    args = parser.parse_args()
    tug = tug_messages()
    for name, msg in tug.items():
        if encode(msg) != rosbags(msg):
            raise SystemExit(f"{name}: encode's bytes differ from rosbags'")
    rows = []
    for name, msg in tug.items():
        baseline = per_message_us(rosbags, msg, args.repeats)
        fast = per_message_us(encode, msg, args.repeats)
        rows.append(f"| {name} | {fast:.2f} µs | {baseline:.2f} µs | {baseline / fast:.1f}× faster | identical |")
    print(f"\nmedian of {args.repeats} batches of {BATCH} calls each\n")
    header = [
        "| message (a tug's, frames under tug_12/) | `encode` (fixed-layout writers) | rosbags' serializer, same run "
        "| ratio | bytes |",
        "| --- | --- | --- | --- | --- |",
    ]
    publish("codec", header + rows)


if __name__ == "__main__":
    main()
