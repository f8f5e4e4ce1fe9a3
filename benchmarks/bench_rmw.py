"""Benchmark of rmw_zenoh's format on the wire: a publish's cost, an image's latency to zenoh_ros2_sdk.

A publish is measured against simbot's plain put before the format, the image's latency against
`simbot ros2`'s, each in the same run:

1. Cost per message, for a Clock, a 720-ray LaserScan and a 640×480 rgb8 Image, each with a
   subscriber on loopback (a second session in this process, its samples kept in Zenoh's own ring
   channel, so no Python runs on arrival): (a) what simbot did before, a plain `zenoh.Publisher.put`
   of the CDR bytes on `<ns>/<topic>` without attachment; (b) `Node.publisher(...).put_raw` of the
   same bytes (rmw_zenoh's key and a 33-byte attachment made per sample); (c) `.put(msg)`, CDR
   encoding included. The variants take turns, in a rotating order, in `--rounds` rounds of
   `--count` puts each; a figure is the median over rounds of each round's median.
2. Image latency: a realtime warehouse server with 640×480 cameras; its `camera_front` taken at
   once by a zenoh_ros2_sdk `ROS2Subscriber` in this process (connected to the server's port, its
   message definitions the ROS 2 wheels' .msg files) and by an rclpy subscriber behind
   `simbot ros2` (bench_ros2's bridge and DDS side). Both measure one and the same frames.

The costs are measured on this host, as simbot's processes run: Zenoh's shared-memory transport (on
by default) carries a payload over 3 KB between two sessions on one machine. DDS discovers by
multicast, so the latency is measured as bench_ros2 measures, in this script run again inside a
private network namespace (`unshare -rn`, loopback only) where one can be made; Zenoh's shared
memory takes no effect there (a 0.9 MB put takes as long with it as without), so both subscribers
get the frames over TCP.

    python benchmarks/bench_rmw.py [--count N] [--rounds R] [--frames F]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from bench_ros2 import INSIDE, RosSide, bridge, free_port, run_in_namespace
from live_runs import connect, stop, wait_ready
from tables import publish

from simbot.bus import BusOptions, Node, encode, messages
from simbot.bus.publisher import CDR_ENCODING
from simbot.bus.rmw import parse_attachment

REPO = Path(__file__).resolve().parents[1]
NAMESPACE = "bench"
VARIANTS = ("plain", "put_raw", "put")
IMAGE = "sensor_msgs/msg/Image"
CAMERA = "camera_front"
CAMERA_SIZE = "640x480"
STAMP = struct.Struct("<iI")
"""builtin_interfaces/Time right after the 4-byte CDR encapsulation, where an Image keeps its header's stamp."""
ARRIVAL_TIMEOUT_S = 0.5
"""How long a put's sample may take to arrive before it counts as lost (DROP congestion control)."""
MATCH_TIMEOUT_S = 10.0
FIRST_FRAME_TIMEOUT_S = 90.0
WARMUP_S = 2.0
LATENCY_OUT = "SIMBOT_BENCH_RMW_LATENCY"
"""Where the run inside the network namespace writes its table's lines for the run that started it."""
SDK_OVERRIDE = 'listen/endpoints=["tcp/127.0.0.1:0"];scouting/multicast/enabled=false'
"""The SDK's session listens on loopback only and scouts nobody; it connects to the server's port."""


def sample_messages() -> dict[str, Any]:
    """A Clock, a 720-ray LaserScan and a 640×480 rgb8 Image, as the server makes them."""
    rng = np.random.default_rng(0)
    scan = messages.laser_scan(
        0, "base_scan_front", (-1.396, 1.396, 0.00389), (0.0, 0.2), (0.08, 10.0), rng.uniform(1, 9, 720)
    )
    image = messages.image(0, "camera_front_optical_frame", rng.integers(0, 255, (480, 640, 3), dtype=np.uint8))
    return {"clock": messages.clock(123_456_789), "lidar_front": scan, "camera_front": image}


def until(condition: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(f"bench_rmw: {what} within {timeout:.0f} s")
        time.sleep(0.05)


Arrivals = zenoh.Subscriber[Any]
"""A subscriber whose samples wait in Zenoh's ring channel (no Python runs as they arrive)."""


def put_us(put: Callable[[], object], arrivals: Arrivals, count: int) -> float:
    """Median microseconds of one put; after each, until its sample has arrived (or is lost), so that every
    put finds Zenoh's queue empty."""
    times = []
    for _ in range(count):
        start = time.perf_counter()
        put()
        times.append(time.perf_counter() - start)
        deadline = start + ARRIVAL_TIMEOUT_S
        while arrivals.try_recv() is None and time.perf_counter() < deadline:
            time.sleep(0.0001)
    return statistics.median(times) * 1e6


def cost_per_message(args: argparse.Namespace) -> list[str]:
    """µs per put of each variant and their ratios to the plain put: the first table, a row per message."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    samples = sample_messages()
    with (
        Node(BusOptions(listen=(endpoint,), namespace=NAMESPACE), "server") as bus,
        Node(BusOptions(connect=(endpoint,), namespace=NAMESPACE), "client") as peer,
    ):
        puts: dict[str, dict[str, tuple[Callable[[], object], Arrivals]]] = {}
        sizes = {}
        for name, msg in samples.items():
            data, typename = encode(msg), msg.__msgtype__
            plain = bus.session.declare_publisher(
                bus.key(name), encoding=CDR_ENCODING, congestion_control=zenoh.CongestionControl.DROP
            )
            rmw = bus.publisher(name, typename)
            before, after = (
                peer.session.declare_subscriber(key, zenoh.handlers.RingChannel(1))
                for key in (plain.key_expr, rmw.data_key)
            )
            encoding = CDR_ENCODING.with_schema(typename)
            puts[name] = {
                "plain": (partial(plain.put, data, encoding=encoding), before),
                "put_raw": (partial(rmw.put_raw, data), after),
                "put": (partial(rmw.put, msg), after),
            }
            sizes[name] = len(data)
        routed: set[tuple[str, str]] = set()

        def all_routed() -> bool:
            """Puts one of each; whether every key's samples have reached the other session."""
            for name, variants in puts.items():
                for variant, (put, arrivals) in variants.items():
                    put()
                    time.sleep(0.05)
                    if arrivals.try_recv() is not None:
                        routed.add((name, variant))
            return len(routed) == len(samples) * len(VARIANTS)

        until(all_routed, MATCH_TIMEOUT_S, "a key's samples did not reach the subscriber")
        for variants in puts.values():  # warm-up
            for put, arrivals in variants.values():
                put_us(put, arrivals, 20)
        figures: dict[str, dict[str, list[float]]] = {name: {v: [] for v in VARIANTS} for name in samples}
        for round_ in range(args.rounds):
            order = VARIANTS[round_ % 3 :] + VARIANTS[: round_ % 3]
            for name, variants in puts.items():
                for variant in order:
                    figures[name][variant].append(put_us(*variants[variant], args.count))
    table = [
        "| message | bytes | (a) plain put, no attachment (before) | (b) `put_raw`: rmw key + attachment "
        "| (c) `put(msg)`: + CDR encoding | b / a | c / a |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, msg in samples.items():
        rounds = figures[name]
        a, b, c = (statistics.median(rounds[v]) for v in VARIANTS)
        b_a = statistics.median(x / y for x, y in zip(rounds["put_raw"], rounds["plain"]))
        c_a = statistics.median(x / y for x, y in zip(rounds["put"], rounds["plain"]))
        kind = msg.__msgtype__.rsplit("/", 1)[-1]
        table.append(
            f"| {name} ({kind}) | {sizes[name]} | {a:.1f} µs | {b:.1f} µs | {c:.1f} µs | {b_a:.2f}× | {c_a:.2f}× |"
        )
        print(table[-1], flush=True)
    table += [
        "",
        "Cost: the median time of one put call (perf_counter around it), each put once the previous one's "
        "sample has reached a subscriber in a second session on loopback, on this host, where Zenoh's shared "
        "memory carries a payload over 3 KB; b / a and c / a are the medians of each round's ratio.",
    ]
    return table


class Frames:
    """Frames one subscriber got: (the image's header stamp, wall-clock ns on arrival, or of its source
    timestamp), added from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.arrivals: list[tuple[int, int]] = []

    def add(self, stamp: int, arrived: int) -> None:
        with self._lock:
            self.arrivals.append((stamp, arrived))

    def since(self, start: int = 0) -> dict[int, int]:
        """Wall-clock ns by stamp of the frames after `start` (wall-clock ns)."""
        with self._lock:
            return {stamp: arrived for stamp, arrived in self.arrivals if arrived > start}


def cdr_stamp(data: bytes) -> int:
    """The header stamp (ns) of an Image's CDR bytes."""
    sec, nanosec = STAMP.unpack_from(data, 4)
    return int(sec) * 1_000_000_000 + int(nanosec)


class SdkSide:
    """A zenoh_ros2_sdk subscriber to `topic` on the server at `port`, with the wheels' .msg files as its only
    message definitions, and a plain subscriber on the SDK's own session (one copy of each sample crosses
    the link) that keeps each frame's attachment source timestamp by its header stamp."""

    def __init__(self, port: int, topic: str, folder: Path) -> None:
        os.environ["ZENOH_CONFIG_OVERRIDE"] = SDK_OVERRIDE
        from zenoh_ros2_sdk import ROS2Subscriber, ZenohSession, get_registry

        for source in (Path(sys.prefix) / "share").glob("*/msg"):
            target = folder / source.parent.name / "msg"
            target.mkdir(parents=True, exist_ok=True)
            for path in source.glob("*.msg"):
                shutil.copyfile(path, target / path.name)
        get_registry(str(folder))  # the registry the SDK uses from now on: nothing is fetched
        self.frames = Frames()
        self.sources = Frames()
        self._session = ZenohSession.get_instance("127.0.0.1", port)
        self._subscriber = ROS2Subscriber(topic, IMAGE, self._arrived, router_port=port)
        self._recorder = self._session.session.declare_subscriber(self._subscriber.keyexpr, self._record)

    def _arrived(self, msg: Any) -> None:
        arrived = time.time_ns()
        self.frames.add(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, arrived)

    def _record(self, sample: zenoh.Sample) -> None:
        if sample.attachment is not None:
            self.sources.add(cdr_stamp(sample.payload.to_bytes()), parse_attachment(sample.attachment.to_bytes())[1])

    def close(self) -> None:
        self._recorder.undeclare()
        self._subscriber.close()
        self._session.close()


def ros_frames(ros: RosSide, topic: str) -> Frames:
    """bench_ros2's DDS side subscribed (raw bytes) to `topic` through the bridge."""
    frames = Frames()
    ros.subscribe(IMAGE, topic, lambda data: frames.add(cdr_stamp(data), time.time_ns()))
    return frames


def p90(values: list[float]) -> float:
    return statistics.quantiles(values, n=10)[-1]


def image_latency(args: argparse.Namespace) -> list[str]:
    """The second table: a 640×480 image's latency from the server to the SDK's subscriber and to rclpy's."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint, topic = f"tcp/127.0.0.1:{port}", f"/{namespace}/{CAMERA}"
    command = ["--world", "warehouse", "--mode", "realtime", "--camera-size", CAMERA_SIZE, "--quiet"]
    server = subprocess.Popen(
        [sys.executable, "-m", "simbot.sim.server", *command, "--listen", endpoint, "--namespace", namespace],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        with connect(endpoint, namespace, server) as node:
            wait_ready(node)
        with tempfile.TemporaryDirectory(prefix="bench_rmw_msgs_") as folder, bridge(endpoint, namespace):
            sdk = SdkSide(port, topic, Path(folder))
            ros = RosSide()
            try:
                sides = {"sdk": sdk.frames, "ros2": ros_frames(ros, topic)}
                until(lambda: all(f.since() for f in sides.values()), FIRST_FRAME_TIMEOUT_S, f"no {CAMERA} on both")
                time.sleep(WARMUP_S)
                start = time.time_ns()

                def enough() -> bool:
                    return min(len(frames.since(start)) for frames in sides.values()) >= args.frames

                until(enough, 120.0, f"not {args.frames} frames on both sides")
                time.sleep(0.5)  # the slower side's last frames
                arrivals = {side: frames.since(start) for side, frames in sides.items()}
            finally:
                ros.close()
                sdk.close()
    finally:
        stop(server, 20.0)
    sources = sdk.sources.since()
    stamps = sorted(arrivals["sdk"].keys() & arrivals["ros2"].keys() & sources.keys())
    ms = {side: [(arrivals[side][stamp] - sources[stamp]) / 1e6 for stamp in stamps] for side in sides}
    rate = (len(stamps) - 1) / ((sources[stamps[-1]] - sources[stamps[0]]) / 1e9)
    median = {side: statistics.median(values) for side, values in ms.items()}
    tail = {side: p90(values) for side, values in ms.items()}
    return [
        f"| subscriber of {CAMERA} (640×480 rgb8, {len(stamps)} frames at {rate:.0f}/s) | median | p90 |",
        "| --- | --- | --- |",
        f"| zenoh_ros2_sdk `ROS2Subscriber`, connected to the server's port | {median['sdk']:.2f} ms "
        f"| {tail['sdk']:.2f} ms |",
        f"| rclpy (raw) behind `simbot ros2` (Zenoh → bridge → DDS) | {median['ros2']:.2f} ms | {tail['ros2']:.2f} ms |",
        f"| SDK / `simbot ros2` | {median['sdk'] / median['ros2']:.2f}× | {tail['sdk'] / tail['ros2']:.2f}× |",
        "",
        "Latency: a frame's arrival in the subscriber's callback (wall clock) less the source timestamp of "
        "rmw_zenoh's attachment, the wall clock at the render worker's put, for the same frames on both sides "
        "(matched by header stamp); the SDK's callback gets the message rosbags decoded, rclpy's the bytes, "
        "as bench_ros2's subscriber. Measured in bench_ros2's private network namespace, where Zenoh's shared "
        "memory takes no effect: both get the frames over TCP.",
    ]


def latency_in_namespace(args: argparse.Namespace) -> list[str]:
    """`image_latency` in bench_ros2's private network namespace (its SETUP), run by this script again
    there; here where none can be made, or where this process is in one already."""
    if os.environ.get(INSIDE):
        return image_latency(args)
    if shutil.which("unshare") is None:
        print("bench_rmw: no private network namespace here (unshare): DDS runs on this host's interfaces")
        return image_latency(args)
    with tempfile.TemporaryDirectory(prefix="bench_rmw_") as folder:
        out = Path(folder) / "latency.json"
        run_in_namespace(Path(__file__).resolve(), ["--frames", str(args.frames)], {LATENCY_OUT: str(out)})
        lines: list[str] = json.loads(out.read_text())
        return lines


def missing_packages() -> list[str]:
    return [name for name in ("rclpy", "zenoh_ros2_sdk") if importlib.util.find_spec(name) is None]


def positive(text: str) -> int:
    """A whole number > 0, for argparse."""
    if not text.strip().isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0, got {text!r}")
    return int(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=positive, default=200, help="puts per variant per round (default 200)")
    parser.add_argument("--rounds", type=positive, default=7, help="rounds of the three variants (default 7)")
    parser.add_argument("--frames", type=positive, default=100, help="images measured on each side (default 100)")
    args = parser.parse_args()
    if os.environ.get(INSIDE) and os.environ.get(LATENCY_OUT):  # the namespace's run for the parent
        Path(os.environ[LATENCY_OUT]).write_text(json.dumps(image_latency(args)))
        return
    cost = cost_per_message(args)
    missing = missing_packages()
    if missing:
        latency = [f"Image latency not measured: {' and '.join(missing)} not installed (pip install 'simbot[ros2]')."]
    else:
        latency = latency_in_namespace(args)
    publish("rmw", [*cost, "", *latency])


if __name__ == "__main__":
    main()
