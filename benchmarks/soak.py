"""Soak benchmark: the warehouse in real time for an hour, every sensor subscribed, the clients running.

Real processes on a fresh loopback port and namespace (multicast scouting off, listening on 127.0.0.1):
`simbot-server --world warehouse` in real time with the SDF's six 640×480 cameras at 30 Hz;
`simbot merger`, `simbot stitcher`, `simbot record` into a temporary bag of every key but the
images (six 640×480 cameras at ~25 Hz are ~140 MB/s: an hour would fill the disk); and this
process: a counting subscriber on every key the server and the clients publish (found on the bus
graph, counted on Zenoh's threads without decoding), and the teleop commands: `cmd_vel` at 10 Hz,
steering the tug round a 1 m circle beside its spawn point from its ground-truth pose. Not
`simbot teleop` through a pty: its keys latch a constant twist, so an hour of it drifts the tug
into a rack; a closed loop keeps it moving, in the open, for hours.

Per key, over a window that starts once every key has delivered: the messages received against
the count the rates imply (rate × sim time elapsed, so a real-time factor below 1 on a loaded
machine is no loss), the rates read from the tug's SDF (sensors, DiffDrive, JointStatePublisher)
and the server's constants (clock, poses, the robot state publisher's tf). A key short of its
count must be explained by world state's own counters (a camera's `skipped` ticks, shown beside
it); anything else beyond a second's worth of messages at the window's edges is a loss. World
state's published `messages` are shown where it counts them; `cmd_vel` sent against its `received`.

Per process (the server, each render worker, each client, this one): RSS (VmRSS) and the load
average at the start, after 5 minutes and at the end; CPU (utime + stime) over the window. A line
per minute goes to stderr. Exit 1 when a key lost messages, a process died, or the tug got stuck.

    python benchmarks/soak.py [--minutes N] [--out FILE]
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port
from live_runs import Counter, children, connect, count_topics, cpu_seconds, machine_busy, wait_ready

from simbot.bus import Node, messages
from simbot.clients.merger import FIXED_TOPICS, MERGED_TOPIC
from simbot.clients.stitcher import IMAGE_TOPIC, INFO_TOPIC
from simbot.clients.topics import live_topics
from simbot.description import Model, load_model
from simbot.description.drive_params import DiffDriveParams
from simbot.description.resources import asset
from simbot.sim.kit.joints import JOINT_STATE_RATE_HZ as STATE_RATE
from simbot.sim.server import ROBOT_NAME
from simbot.sim.systems.clock_publisher import CLOCK_RATE
from simbot.sim.systems.pose_publisher import POSE_RATE

WORLD = "warehouse"
CLIENTS = ("merger", "stitcher", "record")
START_TIMEOUT_S = 180.0
"""From launch to every key delivering: the render worker loads the warehouse first (slow when loaded)."""
SETTLE_S = 5.0
MARK_S = 300.0
"""The middle figure: RSS after 5 minutes, when start-up allocations are over."""
SAMPLE_S = 60.0
EDGE_S = 1.0
"""A second's worth of messages may be in flight at the window's edges: not a loss."""
COMMAND_HZ = 10.0
CENTRE, RADIUS, SPEED = (-2.5, 1.0), 1.0, 0.2
"""The circle the tug drives (m, m, m/s): left of its spawn point at (−2.5, 0), clear of pillars and trolley."""
MIN_DISTANCE_PER_MINUTE = 6.0  # metres per minute of the window (at 0.2 m/s: 12), else the tug is stuck


# --------------------------------------------------------------------------- what each key owes


@dataclass(frozen=True)
class Expectation:
    """A key's rate and the world-state sensors whose counted skips may explain a shortfall."""

    key: str
    rate_hz: float
    source: str
    sensors: tuple[str, ...] = ()
    """Scoped sensor names (`model/link/sensor`) in world state; one: its `messages` is the key's published count."""


def expectations(tug: Model) -> dict[str, Expectation]:
    """Every key the server and the clients publish at a rate, from the SDF and the server's constants."""
    rows = [Expectation("clock", CLOCK_RATE, "server clock")]
    cameras, lidars = [], []
    for link, sensor in tug.sensors():
        scoped, key, rate = f"{ROBOT_NAME}/{link.name}/{sensor.name}", sensor.topic or sensor.name, sensor.update_rate
        source = f"SDF {sensor.name}"
        rows.append(Expectation(key, rate, source, (scoped,)))
        if sensor.type == "camera":
            rows.append(Expectation(f"{key}/camera_info", rate, source, (scoped,)))
            cameras.append((scoped, rate))
        elif "lidar" in sensor.type or "ray" in sensor.type:
            rows.append(Expectation(f"{key}/points", rate, source, (scoped,)))
            lidars.append((scoped, rate))
    tf_rate = STATE_RATE  # the robot state publisher's moving joints; DiffDrive adds odom → base
    for plugin in tug.plugins:
        if plugin.name.endswith("DiffDrive"):
            drive = DiffDriveParams.parse(plugin, tug, ROBOT_NAME)
            rows.append(Expectation(drive.odom_topic, drive.odom_rate, "SDF DiffDrive"))
            tf_rate += drive.odom_rate
        elif plugin.name.endswith("JointStatePublisher"):
            rows.append(
                Expectation(plugin.get("topic") or "joint_states", float(plugin.get("update_rate") or 0), "SDF")
            )
    rows.append(Expectation("tf", tf_rate, "DiffDrive + robot state publisher"))
    lidar_rate = min(rate for _, rate in lidars)
    for key in (*FIXED_TOPICS.values(), MERGED_TOPIC):
        rows.append(Expectation(key, lidar_rate, "merger: a lidar pair", tuple(s for s, _ in lidars)))
    camera_rate = min(rate for _, rate in cameras)
    for key in (IMAGE_TOPIC, INFO_TOPIC):
        rows.append(Expectation(key, camera_rate, "stitcher: a camera set", tuple(s for s, _ in cameras)))
    return {row.key: row for row in rows}


# --------------------------------------------------------------------------- processes


@dataclass
class Proc:
    """One process measured: started here (`popen`), or a child of the server (a render worker)."""

    name: str
    short: str  # in the progress line
    pid: int
    popen: subprocess.Popen[bytes] | None = None
    log: Path | None = None
    rss_kb: dict[str, int] = field(default_factory=dict)
    """VmRSS at each mark ('start', '5 min', 'end')."""
    cpu_s: dict[str, float] = field(default_factory=dict)
    gone: str = ""

    def sample(self, mark: str) -> None:
        self.rss_kb[mark] = rss_kb(self.pid)
        self.cpu_s[mark] = cpu_seconds(self.pid)

    def check(self) -> None:
        """Notes the first sign that the process has ended."""
        if self.gone:
            return
        code = self.popen.poll() if self.popen is not None else None
        if code is not None:
            self.gone = f"exited with code {code}"
        elif not Path(f"/proc/{self.pid}").exists():
            self.gone = "vanished"


def rss_kb(pid: int) -> int:
    """Resident set size (kB) of one process, from /proc/<pid>/status; 0 once it is gone."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as file:
            return next(int(line.split()[1]) for line in file if line.startswith("VmRSS:"))
    except (OSError, StopIteration, ValueError):
        return 0


def start(command: Sequence[str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:  # the child keeps its own descriptor
        return subprocess.Popen(list(command), stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)


def stop(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT (a client closes its bag, the server its workers), then SIGTERM, then SIGKILL."""
    for sig, grace in ((signal.SIGINT, 20.0), (signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        if proc.poll() is None:
            proc.send_signal(sig)
            with suppress(subprocess.TimeoutExpired):
                proc.wait(grace)


@contextmanager
def started(tmp: Path, endpoint: str, namespace: str) -> Iterator[dict[str, subprocess.Popen[bytes]]]:
    """The server and the clients, stopped (clients first) on the way out."""
    bus = ["--namespace", namespace]
    server = [sys.executable, "-m", "simbot.sim.server", "--world", WORLD, "--quiet", "--listen", endpoint, *bus]
    procs = {"server": start(server, tmp / "server.log")}
    images = [f"camera_{side}" for side in ("front", "back", "front_right", "back_right", "front_left", "back_left")]
    record = ["-o", str(tmp / "bag"), *(w for key in (*images, IMAGE_TOPIC) for w in ("--exclude", key))]
    try:
        for name in CLIENTS:
            client = [sys.executable, "-m", f"simbot.clients.{name}", "--connect", endpoint, *bus]
            client += ["--connect-timeout", "60"]
            procs[name] = start([*client, *(record if name == "record" else [])], tmp / f"{name}.log")
        yield procs
    finally:
        for name in reversed(procs):
            stop(procs[name])


# --------------------------------------------------------------------------- teleop


class Circle:
    """cmd_vel at 10 Hz (wall) round a circle, steered from the tug's ground-truth pose."""

    def __init__(self, node: Node) -> None:
        self.sent = 0
        self.distance = 0.0
        self.worst_off = 0.0
        """The farthest (m) the tug was from its circle after the first lap."""
        self._pose: tuple[float, float, float] | None = None
        self._last: tuple[float, float] | None = None
        self._lock = threading.Lock()
        self._publisher = node.publisher("cmd_vel", messages.Twist, drop=False)
        node.subscribe(f"model/{ROBOT_NAME}/pose", "geometry_msgs/msg/PoseStamped", self._on_pose)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="soak-teleop", daemon=True)

    def _on_pose(self, msg: Any) -> None:
        q = msg.pose.orientation
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        with self._lock:
            self._pose = (msg.pose.position.x, msg.pose.position.y, yaw)

    def twist(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """(v, ω): the tangent of the circle (anticlockwise), bent towards it by the distance off it."""
        dx, dy = x - CENTRE[0], y - CENTRE[1]
        off = math.hypot(dx, dy) - RADIUS
        heading = math.atan2(dy, dx) + math.pi / 2 + math.atan(2.0 * off)
        error = math.atan2(math.sin(heading - yaw), math.cos(heading - yaw))
        return SPEED, SPEED / RADIUS + 1.5 * error

    def _run(self) -> None:
        began = time.monotonic()
        while not self._stop.wait(1.0 / COMMAND_HZ):
            with self._lock:
                pose = self._pose
            if pose is None:
                continue
            if self._last is not None:
                self.distance += math.hypot(pose[0] - self._last[0], pose[1] - self._last[1])
            self._last = pose[:2]
            if time.monotonic() - began > 2 * math.pi * RADIUS / SPEED:
                off = abs(math.hypot(pose[0] - CENTRE[0], pose[1] - CENTRE[1]) - RADIUS)
                self.worst_off = max(self.worst_off, off)
            v, w = self.twist(*pose)
            self._publisher.put(messages.twist((v, 0.0, 0.0), (0.0, 0.0, w)))
            self.sent += 1

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self._publisher.put(messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))


# --------------------------------------------------------------------------- the run


@dataclass
class Mark:
    """One moment of the window: wall and sim time, counts, world state, load."""

    wall: float
    state: dict[str, Any]
    counts: dict[str, int]
    sent: int
    load: tuple[float, float, float]
    busy: tuple[float, float]
    """The machine's (busy, total) jiffies of all cores so far."""


def mark(node: Node, counters: dict[str, Counter], teleop: Circle) -> Mark:
    state = node.call(f"world/{WORLD}/state", {}, timeout=10.0)
    counts = {key: c.value() for key, c in counters.items()}
    return Mark(time.monotonic(), state, counts, teleop.sent, os.getloadavg(), machine_busy())


def wait_for_keys(node: Node, wanted: dict[str, Expectation], procs: dict[str, subprocess.Popen[bytes]]) -> list[str]:
    """Every published key once the graph holds all the keys owed (the clients' outputs appear late)."""
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        topics = live_topics(node).values()
        published = sorted(t.name for t in topics if "pub" in t.kinds and t.name != "cmd_vel")  # cmd_vel: ours
        missing = set(wanted) - set(published)
        if not missing:
            return published
        dead = [name for name, p in procs.items() if p.poll() is not None]
        if dead or time.monotonic() > deadline:
            raise SystemExit(f"soak: not on the graph: {', '.join(sorted(missing))}; exited: {dead or 'none'}")
        time.sleep(1.0)


def wait_for_messages(counters: dict[str, Counter], keys: Sequence[str]) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    while missing := [k for k in keys if not counters[k].value()]:
        if time.monotonic() > deadline:
            raise SystemExit(f"soak: no message within {START_TIMEOUT_S:.0f} s on {', '.join(missing)}")
        time.sleep(0.5)


def processes(procs: dict[str, subprocess.Popen[bytes]], logs: Path) -> list[Proc]:
    """The server, its render workers, the clients, this process (multiprocessing's resource tracker,
    a few MB idle, left out)."""
    found = [Proc("server", "server", procs["server"].pid, procs["server"], logs / "server.log")]
    workers = sorted(pid for pid, role in children(procs["server"].pid).items() if role == "render worker")
    found += [Proc(f"server's render worker {n}", f"worker{n}", pid) for n, pid in enumerate(workers, 1)]
    found += [
        Proc(f"simbot {name}", name, p.pid, p, logs / f"{name}.log") for name, p in procs.items() if name != "server"
    ]
    found.append(Proc("soak (subscriber + teleop)", "soak", os.getpid()))
    return found


def progress(m: Mark, first: Mark, procs: Sequence[Proc], teleop: Circle) -> None:
    elapsed = m.wall - first.wall
    rtf = (m.state["sim_time"] - first.state["sim_time"]) / elapsed if elapsed else math.nan
    rss = ", ".join(f"{p.short} {rss_kb(p.pid) / 1024:.0f}" for p in procs)
    print(
        f"[{elapsed / 60:5.1f} min] rtf {rtf:.3f}, load {m.load[0]:.2f}, tug {teleop.distance:.0f} m; RSS MB: {rss}",
        file=sys.stderr,
        flush=True,
    )


def soak(minutes: float, tmp: Path) -> tuple[list[str], bool]:
    """Runs everything for `minutes`; the report's lines and whether it passed."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"soak_{uuid.uuid4().hex[:8]}"
    tug = load_model(asset("urdf/flexley_tug.sdf"))
    owed = expectations(tug)
    with ExitStack() as stack:
        procs = stack.enter_context(started(tmp, endpoint, namespace))
        node = stack.enter_context(connect(endpoint, namespace, procs["server"]))
        wait_ready(node)
        teleop = Circle(node)
        keys = wait_for_keys(node, owed, procs)
        owed |= {
            k: Expectation(k, POSE_RATE, "server poses") for k in keys if k.startswith("model/") and k.endswith("/pose")
        }
        counters = count_topics(node, keys)
        wait_for_messages(counters, list(owed))
        teleop.start()
        time.sleep(SETTLE_S)
        procs_measured, marks = processes(procs, tmp), {}

        def take(name: str) -> None:
            marks[name] = mark(node, counters, teleop)
            for p in procs_measured:
                p.check()
                p.sample(name)

        take("start")
        end, next_sample = marks["start"].wall + minutes * 60, marks["start"].wall + SAMPLE_S
        while (now := time.monotonic()) < end:
            time.sleep(max(0.0, min(next_sample, end) - now))
            for p in procs_measured:
                p.check()
            if "5 min" not in marks and time.monotonic() - marks["start"].wall >= MARK_S and minutes * 60 > MARK_S:
                take("5 min")
            if time.monotonic() >= next_sample:
                progress(mark(node, counters, teleop), marks["start"], procs_measured, teleop)
                next_sample += SAMPLE_S
        take("end")
        teleop.stop()
    # the clients and the server are stopped: record's bag is closed
    return report(owed, keys, marks, procs_measured, teleop, minutes, tmp)


# --------------------------------------------------------------------------- report


def sensor_delta(first: Mark, last: Mark, scoped: str, figure: str) -> int:
    """How much one of world state's figures for a sensor grew over the window."""
    return int(
        last.state["sensors"].get(scoped, {}).get(figure, 0) - first.state["sensors"].get(scoped, {}).get(figure, 0)
    )


def key_rows(
    owed: dict[str, Expectation], keys: Sequence[str], first: Mark, last: Mark, namespace_cmd: str
) -> tuple[list[str], list[str]]:
    """The per-key table and the keys that lost messages."""
    sim_s = last.state["sim_time"] - first.state["sim_time"]
    lines = [
        "| key | rate (Hz) | expected (rate × sim time) | published (world state) | skipped (world state) "
        "| received | unexplained loss | verdict |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    losses = []
    for key in keys:
        received = last.counts[key] - first.counts[key]
        row = owed.get(key)
        if row is None:
            lines.append(f"| {key} | on change (latched) | — | — | — | {received} | — | — |")
            continue
        expected = row.rate_hz * sim_s
        skipped = max((sensor_delta(first, last, s, "skipped") for s in row.sensors), default=0)
        published = str(sensor_delta(first, last, row.sensors[0], "messages")) if len(row.sensors) == 1 else "—"
        loss = expected - skipped - received
        lost = loss > row.rate_hz * EDGE_S + 2
        losses += [key] if lost else []
        lines.append(
            f"| {key} | {row.rate_hz:g} | {expected:.0f} | {published} | {skipped} | {received} "
            f"| {max(0.0, loss):.0f} | {'LOSS' if lost else 'ok'} |"
        )
    sent = last.sent - first.sent
    got = last.state["received"].get(namespace_cmd, 0) - first.state["received"].get(namespace_cmd, 0)
    short = sent - got > COMMAND_HZ * EDGE_S + 2
    losses += ["cmd_vel"] if short else []
    lines.append(
        f"| cmd_vel (in) | {COMMAND_HZ:g} (wall) | {sent} sent | — | — | {got} | {max(0, sent - got)} "
        f"| {'LOSS' if short else 'ok'} |"
    )
    return lines, losses


def process_rows(procs: Sequence[Proc], marks: dict[str, Mark]) -> list[str]:
    wall = marks["end"].wall - marks["start"].wall
    lines = [
        "| process | RSS start (MB) | RSS 5 min (MB) | RSS end (MB) | CPU (s) | CPU (% of one core) | ended early |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for p in procs:
        rss = [f"{p.rss_kb[m] / 1024:.0f}" if m in p.rss_kb else "—" for m in ("start", "5 min", "end")]
        cpu = p.cpu_s["end"] - p.cpu_s["start"]
        lines.append(f"| {p.name} | {' | '.join(rss)} | {cpu:.0f} | {100 * cpu / wall:.1f} | {p.gone or 'no'} |")
    return lines


def report(
    owed: dict[str, Expectation],
    keys: Sequence[str],
    marks: dict[str, Mark],
    procs: Sequence[Proc],
    teleop: Circle,
    minutes: float,
    tmp: Path,
) -> tuple[list[str], bool]:
    first, last = marks["start"], marks["end"]
    wall = last.wall - first.wall
    sim_s = last.state["sim_time"] - first.state["sim_time"]
    cmd_key = next((k for k in last.state["received"] if k.endswith("/cmd_vel") or k == "cmd_vel"), "cmd_vel")
    table, losses = key_rows(owed, keys, first, last, cmd_key)
    dead = [f"{p.name} {p.gone}{last_words(p.log)}" for p in procs if p.gone]
    stuck = teleop.distance < MIN_DISTANCE_PER_MINUTE * wall / 60
    bag = sum(f.stat().st_size for f in (tmp / "bag").glob("*") if f.is_file())
    loads = ", ".join(f"{m} {marks[m].load[0]:.2f}" for m in ("start", "5 min", "end") if m in marks)
    busy = (last.busy[0] - first.busy[0]) / max(1.0, last.busy[1] - first.busy[1])
    ours = sum(p.cpu_s["end"] - p.cpu_s["start"] for p in procs) / wall
    camera: dict[str, Any] = next((f for f in last.state["sensors"].values() if "renderer" in f), {})
    width, height = camera.get("size", ("?", "?"))
    lines = [
        f"Soak, {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC: {wall / 60:.1f} min of wall time "
        f"(asked {minutes:g}), {sim_s:.1f} s of sim time, real-time factor {sim_s / wall:.3f}; "
        f"{os.cpu_count()} cores, load average (1 min) {loads}; the machine busy {busy:.0%} of its cores, "
        f"{ours:.2f} cores' worth of it the processes below.",
        f"Cameras {width}×{height}, renderer {camera.get('renderer', '?')}.",
        f"The tug drove {teleop.distance:.0f} m ({teleop.distance / sim_s:.2f} m/s of sim time), at most "
        f"{teleop.worst_off:.2f} m off its circle; the bag (every key but the images) holds {bag / 1e6:.0f} MB. "
        f"World state's dropped inputs: {last.state['dropped'] or 'none'}.",
        "",
        *table,
        "",
        *process_rows(procs, marks),
        "",
        f"Losses: {', '.join(losses) or 'none'}. Processes that ended early: {', '.join(dead) or 'none'}."
        + (" The tug was stuck." if stuck else ""),
    ]
    return lines, not losses and not dead and not stuck


def last_words(log: Path | None) -> str:
    """The last lines a process wrote before it ended, for the report."""
    if log is None or not log.exists():
        return ""
    tail = log.read_text(errors="replace").strip().splitlines()[-3:]
    return (": " + " / ".join(tail)) if tail else ""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="length of the measured window (default 60)")
    parser.add_argument("--out", type=Path, help="also write the report (markdown) to this file")
    args = parser.parse_args()
    if not args.minutes > 0:
        parser.error(f"--minutes: expected a number > 0, got {args.minutes:g}")
    with tempfile.TemporaryDirectory(prefix="soak_") as tmp:
        lines, passed = soak(args.minutes, Path(tmp))
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
    sys.exit(0 if passed else 1)


if __name__ == "__main__":
    main()
