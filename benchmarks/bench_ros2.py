"""Benchmark of `simbot ros2`: the latency and CPU the bridge adds per message, against a bare rclpy publish in the same run.

Per message kind (a 720-ray LaserScan, a 640×480 rgb8 Image), one payload at a time:

- latency: a Zenoh put on the bus → the bridge → DDS → a raw rclpy subscription in this process,
  against a bare rclpy publisher (a DDS participant of its own in this process) publishing the
  same bytes to the same subscriber: the median of `--count` pings each way;
- CPU: the bridge process's CPU time (/proc) over a burst of `--count` messages, less what it
  spends idle over as long, per message; against a bare rclpy publisher process publishing the
  same bytes at the same rate (its own CPU time over the burst, per message).

Then the whole bus: a real server in real time (the warehouse: IMU 200 Hz, clock 100, odometry,
poses, joint states, lidars), a ROS node subscribing every topic but the cameras, and the bridge's
CPU over `--seconds` as a share of one core.

DDS discovers by multicast on every interface, so the benchmark runs itself again inside a
private network namespace (`unshare -rn`, loopback only) where it can make one.

    python benchmarks/bench_ros2.py [--count N] [--seconds S]
"""

from __future__ import annotations

import argparse
import os
import queue
import shlex
import shutil
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from tables import publish

from simbot.bus import BusOptions, Node, encode, messages

REPO = Path(__file__).resolve().parents[1]
NAMESPACE = "bench"
SETUP = "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"
INSIDE = "SIMBOT_BENCH_NETNS"
TICKS = os.sysconf("SC_CLK_TCK")
WAIT_S = 30.0
KINDS = {"lidar_front": ("sensor_msgs/msg/LaserScan", 100.0), "camera_front": ("sensor_msgs/msg/Image", 30.0)}
"""Each kind's ROS type and the rate of its CPU burst (Hz)."""

BARE_PUBLISHER = """
import sys, time, rclpy
from rclpy.qos import QoSProfile
from {module} import {name} as T
rclpy.init()
node = rclpy.create_node("bare")
pub = node.create_publisher(T, sys.argv[1], QoSProfile(depth=10))
data = sys.stdin.buffer.read()
while pub.get_subscription_count() == 0:
    time.sleep(0.01)
count, period = int(sys.argv[2]), 1.0 / float(sys.argv[3])
start = time.process_time()
for i in range(count):
    pub.publish(data)
    time.sleep(period)
print(time.process_time() - start, flush=True)
time.sleep(0.5)
"""


def payloads() -> dict[str, bytes]:
    """One CDR payload of each kind, as the server writes them."""
    rng = np.random.default_rng(0)
    scan = messages.laser_scan(
        0, "base_scan_front", (-1.396, 1.396, 0.00389), (0.0, 0.2), (0.08, 10.0), rng.uniform(1, 9, 720)
    )
    image = messages.image(0, "camera_front_optical_frame", rng.integers(0, 255, (480, 640, 3), dtype=np.uint8))
    return {"lidar_front": encode(scan), "camera_front": encode(image)}


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


@contextmanager
def bridge(endpoint: str, namespace: str, *args: str) -> Iterator[subprocess.Popen[bytes]]:
    process = subprocess.Popen(
        [sys.executable, "-m", "simbot.clients.ros2", "--connect", endpoint, "--namespace", namespace, *args],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        yield process
    finally:
        process.terminate()
        process.wait(timeout=10)


class RosSide:
    """This process's DDS side: raw subscriptions whose arrivals are queued, spun on a thread."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("bench", context=self.context)
        self.arrivals: queue.SimpleQueue[float] = queue.SimpleQueue()
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        threading.Thread(target=self._executor.spin, daemon=True).start()

    def subscribe(self, typename: str, topic: str, callback: Callable[[Any], None] | None = None) -> None:
        from rclpy.qos import QoSProfile

        from simbot.clients.ros2 import ros_type

        self.node.create_subscription(
            ros_type(typename),
            topic,
            callback or (lambda _: self.arrivals.put(time.perf_counter())),
            QoSProfile(depth=10),
            raw=True,
        )

    def ping_ms(self, send: Callable[[], None], count: int) -> float:
        """Median milliseconds from `send` to the arrival, one message at a time."""
        times = []
        for _ in range(count):
            start = time.perf_counter()
            send()
            times.append(self.arrivals.get(timeout=WAIT_S) - start)
            time.sleep(0.005)
        return statistics.median(times) * 1e3

    def close(self) -> None:
        import rclpy

        self._executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def bare_ros_publisher(ros: RosSide, typename: str, topic: str) -> Callable[[bytes], None]:
    """A bare rclpy publisher in a DDS participant of its own, with the bridge's QoS."""
    import rclpy
    from rclpy.qos import QoSProfile

    from simbot.clients.ros2 import ros_type

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bare_" + topic.rsplit("/", 1)[-1], context=context)
    publisher = node.create_publisher(ros_type(typename), topic, QoSProfile(depth=10))
    deadline = time.monotonic() + WAIT_S
    while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    return publisher.publish


def bare_cpu_per_message_ms(typename: str, topic: str, data: bytes, count: int, rate: float) -> float:
    """CPU of a bare rclpy publisher process publishing `count` messages at `rate`, per message."""
    package, _, name = typename.split("/")
    script = BARE_PUBLISHER.format(module=f"{package}.msg", name=name)
    done = subprocess.run(
        [sys.executable, "-c", script, topic, str(count), str(rate)],
        input=data,
        capture_output=True,
        timeout=120,
        check=True,
    )
    return float(done.stdout.split()[0]) / count * 1e3


def drain(arrivals: queue.SimpleQueue[float]) -> None:
    while not arrivals.empty():
        arrivals.get()


def per_message(args: argparse.Namespace) -> list[str]:
    """Latency and CPU per message, bridge against bare: the docs' table, a row per message."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with (
        Node(BusOptions(listen=(endpoint,), namespace=NAMESPACE), "server") as bus,
        bridge(endpoint, NAMESPACE) as process,
    ):
        ros = RosSide()
        table = [
            "| message | bytes | latency, bare rclpy publish → subscriber | latency, Zenoh put → bridge → subscriber "
            "| CPU per message, bare publisher process | CPU per message, bridge |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for key, data in payloads().items():
            typename, rate = KINDS[key]
            publisher = bus.publisher(key, typename)
            ros.subscribe(typename, f"/{NAMESPACE}/{key}")
            ros.subscribe(typename, f"/{NAMESPACE}/bare_{key}")
            send = partial(publisher.put_raw, data)
            wait_first(ros, send)
            bridged = ros.ping_ms(send, args.count)
            bare = ros.ping_ms(partial(bare_ros_publisher(ros, typename, f"/{NAMESPACE}/bare_{key}"), data), args.count)
            bridge_cpu = bridge_cpu_per_message_ms(process.pid, ros, send, args.count, rate)
            ros.subscribe(typename, f"/{NAMESPACE}/cpu_{key}", lambda _: None)
            bare_cpu = bare_cpu_per_message_ms(typename, f"/{NAMESPACE}/cpu_{key}", data, args.count, rate)
            table.append(
                f"| {key} ({typename.rsplit('/', 1)[-1]}) | {len(data)} | {bare:.2f} ms "
                f"| {bridged:.2f} ms = {bridged / bare:.1f}× bare (+{bridged - bare:.2f} ms) | {bare_cpu:.2f} ms "
                f"| {bridge_cpu:.2f} ms = {bridge_cpu / bare_cpu:.1f}× bare |"
            )
            print(table[-1], flush=True)
        ros.close()
    return table


def wait_first(ros: RosSide, send: Callable[[], None]) -> None:
    """Until a put reaches the subscriber (the bridge has seen the key and a DDS subscriber for it)."""
    deadline = time.monotonic() + WAIT_S
    while ros.arrivals.empty():
        if time.monotonic() > deadline:
            raise SystemExit("the bridge carried nothing within 30 s")
        send()
        time.sleep(0.1)
    time.sleep(0.5)
    drain(ros.arrivals)


def bridge_cpu_per_message_ms(pid: int, ros: RosSide, send: Callable[[], None], count: int, rate: float) -> float:
    """The bridge's CPU over a burst at `rate`, less its idle CPU over as long, per message."""
    seconds = count / rate
    idle_start = cpu_s(pid)
    time.sleep(seconds)
    idle = cpu_s(pid) - idle_start
    start = cpu_s(pid)
    for _ in range(count):
        send()
        time.sleep(1.0 / rate)
    busy = cpu_s(pid) - start
    drain(ros.arrivals)
    return max(busy - idle, 0.0) / count * 1e3


def counter(counts: dict[str, int], name: str) -> Callable[[Any], None]:
    """A subscription callback counting the messages of `name`."""

    def count(_: Any) -> None:
        counts[name] = counts.get(name, 0) + 1

    return count


def whole_bus(args: argparse.Namespace) -> str:
    """The bridge's share of a core with a ROS node subscribing every topic but the cameras, as a sentence."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    server = subprocess.Popen(
        [sys.executable, "-m", "simbot.sim.server", "--listen", endpoint, "--namespace", "bus", "--quiet"],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        time.sleep(8.0)  # the warehouse loads
        with bridge(endpoint, "bus") as process:
            ros = RosSide()
            counts: dict[str, int] = {}
            time.sleep(3.0)  # the bridge's first look at the graph
            topics = [
                (name, types[0])
                for name, types in ros.node.get_topic_names_and_types()
                if name.startswith("/bus/") and "camera" not in name
            ]
            for name, typename in topics:
                ros.subscribe(typename, name, counter(counts, name))
            time.sleep(2.0)
            start, received = cpu_s(process.pid), sum(counts.values())
            time.sleep(args.seconds)
            share = (cpu_s(process.pid) - start) / args.seconds
            rate = (sum(counts.values()) - received) / args.seconds
            ros.close()
            return (
                f"The whole bus without cameras: {len(topics)} topics, {rate:.0f} messages/s carried, "
                f"the bridge's CPU {share * 100:.1f} % of a core."
            )
    finally:
        server.terminate()
        server.wait(timeout=10)


def run_in_namespace(script: Path, argv: Sequence[str], env: Mapping[str, str] | None = None) -> None:
    """Runs `script` with `argv` inside a private network namespace (SETUP, INSIDE set, `env` added);
    its failure is this process's exit code."""
    words = " ".join(shlex.quote(word) for word in (sys.executable, str(script), *argv))
    environment = dict(os.environ, **{INSIDE: "1"}, **(env or {}))
    done = subprocess.run(["unshare", "-rn", "sh", "-c", f"{SETUP} && exec {words}"], env=environment, check=False)
    if done.returncode != 0:
        raise SystemExit(done.returncode)


def reexec_in_namespace() -> bool:
    """Run this benchmark again inside a private network namespace; False where none can be made."""
    if os.environ.get(INSIDE) or shutil.which("unshare") is None:
        return False
    run_in_namespace(Path(__file__).resolve(), sys.argv[1:])
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=200, help="messages per measurement")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the whole bus is measured")
    args = parser.parse_args()
    try:
        import rclpy  # noqa: F401
    except ImportError:
        print("bench_ros2: skipped: rclpy is not installed (pip install 'simbot[ros2]')")
        return
    if reexec_in_namespace():
        return
    if not os.environ.get(INSIDE):
        print("bench_ros2: no private network namespace here (unshare): DDS runs on this host's interfaces")
    table = per_message(args)
    publish("ros2", [*table, "", whole_bus(args)])


if __name__ == "__main__":
    main()
