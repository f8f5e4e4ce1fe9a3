"""A simbot server (or the main job, started by `simbot launch`) run as a subprocess and measured
from outside, as a user would see it: the samples a client receives per wall second, the
real-time factor from world state, and the CPU each process took (/proc), so a benchmark's
figures are what a subscriber gets, not what the server thinks it sent.

`run_server` starts it on a fresh loopback port and namespace, subscribes a counting client
(`count_topics`: samples counted, never decoded), waits until every topic has delivered and the
loop has settled, and returns a `Run`; `describe` prints a run's raw figures.
"""

from __future__ import annotations

import math
import os
import shlex
import signal
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port

from simbot.bus import BusOptions, Node, messages
from simbot.description import load_model
from simbot.description.resources import asset

WORLD = "warehouse"
CAMERAS = tuple(s.name for _, s in load_model(asset("urdf/flexley_tug.sdf")).sensors() if s.type == "camera")
"""The tug's six cameras, read from its SDF (each publishes on its own name)."""
LIDARS = ("lidar_front", "lidar_back")
IMU = "imu_scan"
RTF_TARGET = 0.98
FIRST_FRAME_TIMEOUT_S = 90.0
"""The render worker loads the warehouse before the first frame (seconds on a small machine)."""
SETTLE_S = 2.0
"""After the last camera's first frame: the real-time pacer and the pool settle."""
TICKS = os.sysconf("SC_CLK_TCK")


class Counter:
    """Samples on one key, counted on Zenoh's thread without decoding (see the module docstring)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.count = 0
        self.subscriber: object = None
        """Kept so that the subscriber lives as long as the counter."""

    def __call__(self, _sample: Any) -> None:
        with self._lock:
            self.count += 1

    def value(self) -> int:
        with self._lock:
            return self.count


def count_topics(node: Node, topics: Sequence[str]) -> dict[str, Counter]:
    """A counting subscriber per topic (it also makes the server see a subscriber: cameras render)."""
    counters = {}
    for topic in topics:
        counter = counters[topic] = Counter()
        counter.subscriber = node.session.declare_subscriber(node.graph.any_type_key(node.key(topic)), counter)
    return counters


def stop(proc: subprocess.Popen[bytes], grace: float = 60.0) -> None:
    """SIGINT, as Ctrl-C ends a simbot program; SIGKILL after `grace` seconds."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(grace)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of one process so far (/proc/<pid>/stat utime, stime)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as file:
            fields = file.read().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / TICKS


def schedstat(pid: int) -> tuple[float, float]:
    """(seconds on a CPU, seconds runnable but waiting for one) of one thread so far
    (/proc/<pid>/schedstat; the process id names its main thread, where the physics loop runs)."""
    try:
        with open(f"/proc/{pid}/schedstat", encoding="ascii") as file:
            on_cpu, waiting = file.read().split()[:2]
    except (OSError, ValueError):
        return math.nan, math.nan
    return int(on_cpu) / 1e9, int(waiting) / 1e9


def children(pid: int) -> dict[int, str]:
    """The server's child processes (render workers, multiprocessing's resource tracker), by role."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="ascii") as file:
                ppid = int(file.read().rsplit(")", 1)[1].split()[1])
            if ppid != pid:
                continue
            with open(f"/proc/{entry}/cmdline", "rb") as file:
                cmdline = file.read().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, ValueError, IndexError):
            continue
        found[int(entry)] = "resource tracker" if "resource_tracker" in cmdline else "render worker"
    return found


def machine_busy() -> tuple[float, float]:
    """(busy, total) jiffies of all cores so far (/proc/stat): how saturated the machine was."""
    with open("/proc/stat", encoding="ascii") as file:
        values = [int(v) for v in file.readline().split()[1:]]
    idle = values[3] + values[4]
    return sum(values) - idle, sum(values)


@dataclass
class Run:
    """What one server run achieved over its measuring window."""

    wall_s: float
    rtf: float
    """Sim seconds advanced per wall second over the window."""
    state_rtf: float
    """The server's own one-second real-time factor at the end of the window."""
    received: dict[str, int]
    """Samples the client received per topic in the window."""
    sensors: dict[str, dict[str, float]]
    """Per sensor: messages and skipped in the window (world state), and its reported rate_hz."""
    server_cpu: float
    """CPU seconds per wall second of the server process (physics thread + Zenoh threads)."""
    loop_cpu: float
    """CPU seconds per wall second of the server's main thread (the simulation loop)."""
    loop_wait: float
    """Seconds per wall second the main thread was runnable but had no CPU."""
    worker_cpu: float
    """CPU seconds per wall second of all render workers together."""
    worker_wait: float
    """Seconds per wall second the render workers were runnable but had no CPU."""
    client_cpu: float
    """CPU seconds per wall second of this benchmark process (the counting client)."""
    machine_busy: float
    """Busy fraction of all cores."""
    cores: int
    intervals: list[float]
    """Real-time factor of each half second of the window: whether time was lost evenly or in stalls."""
    renderer: str | None = None

    @property
    def others_cpu(self) -> float:
        """Cores' worth of CPU that processes outside this benchmark took (a shared machine)."""
        return self.machine_busy * self.cores - self.server_cpu - self.worker_cpu - self.client_cpu

    def per_second(self, topic: str) -> float:
        return self.received.get(topic, 0) / self.wall_s


def connect(endpoint: str, namespace: str, proc: subprocess.Popen[bytes]) -> Node:
    deadline = time.monotonic() + 30
    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"simbot-server exited with code {proc.returncode} at start")
        try:
            return Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=1.0), "client")
        except OSError:
            if time.monotonic() > deadline:
                raise


def _state(node: Node) -> dict[str, Any]:
    return node.call(f"world/{WORLD}/state", {}, timeout=5.0)


def wait_ready(node: Node) -> None:
    deadline = time.monotonic() + 30
    while True:
        try:
            if _state(node).get("ok"):
                return
        except (TimeoutError, RuntimeError):
            pass
        if time.monotonic() > deadline:
            raise RuntimeError("the server's world control did not answer within 30 s")
        time.sleep(0.05)


def _wait_first(counters: dict[str, Counter], topics: Sequence[str], proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + FIRST_FRAME_TIMEOUT_S
    while not all(counters[t].value() for t in topics):
        if proc.poll() is not None or time.monotonic() > deadline:
            missing = [t for t in topics if not counters[t].value()]
            raise RuntimeError(f"no message on {missing} within {FIRST_FRAME_TIMEOUT_S:.0f} s")
        time.sleep(0.1)


def run_server(
    mode: str,
    topics: Sequence[str],
    seconds: float,
    extra: Sequence[str] = (),
    drive: bool = False,
    world: str = WORLD,
    clients: Sequence[str] | None = None,
) -> Run:
    """`simbot-server` on a fresh loopback port and namespace, `topics` subscribed; measured over
    `seconds` of wall time once every subscribed topic has delivered and the loop has settled.
    `world`: a name or an SDF path whose `<world>` is named warehouse (world control's key).
    `clients`: the server started by `simbot launch` with these clients, as `make run` starts it."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    server = ["--mode", mode, "--quiet", *extra]
    if clients is None:
        command = [sys.executable, "-m", "simbot.sim.server", "--world", world, *server]
    else:
        launch = ["launch", "--world", world, "--clients", ",".join(clients), f"--server-args={shlex.join(server)}"]
        command = [sys.executable, "-m", "simbot.cli", *launch]
    bus = ["--listen", endpoint, "--namespace", namespace]
    proc = subprocess.Popen([*command, *bus], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with connect(endpoint, namespace, proc) as node:
            wait_ready(node)
            counters = count_topics(node, topics)
            if drive:
                node.publisher("cmd_vel", messages.Twist, drop=False).put(
                    messages.twist((0.3, 0.0, 0.0), (0.0, 0.0, 0.1))
                )
            _wait_first(counters, topics, proc)
            time.sleep(SETTLE_S)
            return _measure(node, proc.pid if clients is None else _server_pid(proc.pid), counters, seconds)
    finally:
        proc.send_signal(signal.SIGINT)  # launch ends its children on Ctrl-C; the server ends on it too
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _server_pid(launch: int) -> int:
    """The server among launch's children."""
    for pid in children(launch):
        with open(f"/proc/{pid}/cmdline", "rb") as file:
            if b"simbot.sim.server" in file.read():
                return pid
    raise RuntimeError(f"launch (pid {launch}) runs no simbot.sim.server")


SAMPLE_S = 0.5


def _sample(node: Node, seconds: float) -> tuple[dict[str, Any], list[float]]:
    """The world state at the end of `seconds`, and the real-time factor of each half second."""
    state, wall = _state(node), time.perf_counter()
    end, intervals = wall + seconds, []
    while wall < end:
        time.sleep(max(0.0, min(SAMPLE_S, end - wall)))
        now_state, now = _state(node), time.perf_counter()
        intervals.append((now_state["sim_time"] - state["sim_time"]) / (now - wall))
        state, wall = now_state, now
    return state, intervals


def _sched(pids: Sequence[int]) -> tuple[float, float]:
    stats = [schedstat(p) for p in pids]
    return sum(s[0] for s in stats), sum(s[1] for s in stats)


def _measure(node: Node, pid: int, counters: dict[str, Counter], seconds: float) -> Run:
    workers = [p for p, role in children(pid).items() if role == "render worker"]
    before = _state(node)
    counts0 = {t: c.value() for t, c in counters.items()}
    cpu0, wcpu0, me0, busy0 = (
        cpu_seconds(pid),
        sum(cpu_seconds(w) for w in workers),
        time.process_time(),
        machine_busy(),
    )
    loop0, wsched0 = schedstat(pid), _sched(workers)
    wall0 = time.perf_counter()
    after, intervals = _sample(node, seconds)
    wall = time.perf_counter() - wall0
    cpu1, wcpu1, me1, busy1 = (
        cpu_seconds(pid),
        sum(cpu_seconds(w) for w in workers),
        time.process_time(),
        machine_busy(),
    )
    loop1, wsched1 = schedstat(pid), _sched(workers)
    counts = {t: c.value() - counts0[t] for t, c in counters.items()}
    sensors = {}
    for name, figures in after["sensors"].items():
        old = before["sensors"].get(name, {})
        sensors[name] = {
            "messages": figures.get("messages", 0) - old.get("messages", 0),
            "skipped": figures.get("skipped", 0) - old.get("skipped", 0),
            "rate_hz": figures.get("rate_hz", 0.0),
        }
    renderer = next((f["renderer"] for f in after["sensors"].values() if "renderer" in f), None)
    return Run(
        wall_s=wall,
        rtf=(after["sim_time"] - before["sim_time"]) / wall,
        state_rtf=after["real_time_factor"],
        received=counts,
        sensors=sensors,
        server_cpu=(cpu1 - cpu0) / wall,
        loop_cpu=(loop1[0] - loop0[0]) / wall,
        loop_wait=(loop1[1] - loop0[1]) / wall,
        worker_cpu=(wcpu1 - wcpu0) / wall,
        worker_wait=(wsched1[1] - wsched0[1]) / wall,
        client_cpu=(me1 - me0) / wall,
        machine_busy=(busy1[0] - busy0[0]) / max(1, busy1[1] - busy0[1]),
        cores=len(os.sched_getaffinity(0)),
        intervals=intervals,
        renderer=renderer,
    )


# --------------------------------------------------------------------------- report


def camera_fps(run: Run) -> float:
    """Images per wall second the client received, all cameras together."""
    return sum(run.per_second(c) for c in CAMERAS)


def verdict(ok: bool) -> str:
    return "PASS" if ok else "NOT REACHED"


def describe(label: str, run: Run) -> None:
    """The raw figures of one run."""
    print(
        f"\n{label}: {run.wall_s:.1f} s wall, rtf {run.rtf:.3f} (server's 1 s window {run.state_rtf:.3f}), "
        f"renderer {run.renderer}"
    )
    slow = [f"{r:.2f}" for r in run.intervals if r < RTF_TARGET]
    print(
        f"  half-second real-time factors: min {min(run.intervals):.3f}, median {statistics.median(run.intervals):.3f}; "
        f"{len(slow)} of {len(run.intervals)} below {RTF_TARGET}: {' '.join(slow) or '-'}"
    )
    print(
        f"  CPU per wall second: server {run.server_cpu:.2f} (its loop thread {run.loop_cpu:.2f}, runnable without a CPU "
        f"{run.loop_wait:.3f}), render workers {run.worker_cpu:.2f} (runnable without a CPU {run.worker_wait:.2f}), "
        f"this client {run.client_cpu:.2f}, other processes on the machine {run.others_cpu:.2f}; "
        f"machine busy {run.machine_busy:.0%} of {run.cores} cores"
    )
    for topic, count in run.received.items():
        figures = run.sensors.get(topic.replace("imu_scan", "imu_sensor"), {})
        print(
            f"  {topic:20s} received {count:5d} ({count / run.wall_s:6.2f}/s wall); server: "
            f"{figures.get('messages', 0):5.0f} published, {figures.get('skipped', 0):5.0f} skipped, "
            f"rate {figures.get('rate_hz', 0):.2f} Hz sim"
        )
