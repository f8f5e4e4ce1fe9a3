"""Benchmark of a fleet: N Flexley Tugs, dynamic and kinematic, N = 1, 10, 20, 50, 100 (as far as each gets).

Every figure is measured in the same run, the bare loops interleaved and each the median of
`--repeats` runs (a shared machine is noisy); the bare loops count their own CPU time, the servers
wall time (what real time means) and their own CPU time:

1. baseline: a bare PyBullet loop at 1 kHz, the plain URDF (`urdf/flexley_tug.urdf`, 20 joints,
   12 of them castor gimbals) loaded N times by `loadURDF` on a plane, nothing but `stepSimulation`;
2. simbot's loader (castors fixed, fixed links merged: 5 links a tug), the same bare loop;
3. `Physics.step`: simbot's loader plus its wheel-friction model, what the server steps;
4. `simbot-server --robots N` (each tug in its own namespace, its own keys), dynamic: the
   real-time factor it holds in real-time mode (wall time, on this machine as loaded as it is) and
   fast mode's sim seconds per CPU second of the server process (≥ 1: real time on a core of its
   own). The fleet's tug is the Flexley Tug less its six cameras: two lidars at 5 Hz, an IMU at
   200 Hz, odometry and tf at 50 Hz, joint states and tf at 30 Hz;
5. the same with `--physics kinematic` (5 ms steps), the tug without its IMU (the issue's goal:
   two lidars, odometry and tf), and in fast mode with the IMU at 200 Hz too.

The dynamic rows stop after the first N whose server, in fast mode, makes less than half a sim
second per CPU second (the real-time factor on a shared machine counts the others' work).

Then issues 48's and 58's goals, each a real-time run of the full Flexley Tug (every sensor declared: six
cameras, two lidars, the IMU) on the empty world, with a client in this process reading ten tugs'
scans and odometry (decoded), against the bare loop of the same tugs in the same run (kinematic:
`Physics.step` of the kinematic world, 5 ms steps; dynamic: the loader's bare loop):

6. a hundred kinematic tugs, the server pinned to one CPU (`taskset`): the real-time factor held,
   and the CPU it took per tug per sim second;
7. two hundred kinematic tugs in two zones (`simbot launch --zones 2`: two servers, launch's
   router, the handover watching the fleet), on every core: the slower zone's factor held, and
   the CPU of every process the launch started per tug per sim second;
8. five hundred kinematic tugs on one CPU, and a thousand on every core (issue 58), the same way;
9. ten dynamic tugs on one CPU, and twenty in two zones, the same way.

    python benchmarks/bench_fleet.py [--fleets 1,10,20,50,100] [--seconds S] [--repeats R] [--kinematic-only]
                                     [--goals-only | --no-goals]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench_server import free_port
from live_runs import cpu_seconds, stop
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description import load_model, load_world
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.bullet import pb
from simbot.sim.physics import Physics
from simbot.sim.physics.kinematic_world import KINEMATIC_STEP_S, kinematic

STEP_S = 0.001
SPACING_M = 1.0
"""Tugs side by side along y, 0.5 m apart (the chassis is 0.5 m wide)."""
SPAWN_Z = 0.1
SETTLE_STEPS = 300
SETTLE_S = 2.0
DRIVE = (0.3, 0.0, 0.05)
"""The kinematic bare loop's twist of every tug (forward m/s, lateral m/s, turn rad/s): a kinematic
step of standing tugs does nothing, so its baseline drives them (a move each, one collision pass a step)."""
WORLD = "empty"


def row(n: int) -> list[tuple[float, float, float]]:
    return [(0.0, i * SPACING_M, SPAWN_Z) for i in range(n)]


@contextmanager
def plain_world(n: int) -> Iterator[Callable[[], None]]:
    """The baseline: the plain URDF N times on a plane; yields one bare step."""
    client = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -9.8, physicsClientId=client)
    pb.setTimeStep(STEP_S, physicsClientId=client)
    pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=client)
    pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client), physicsClientId=client)
    urdf = str(asset("urdf/flexley_tug.urdf"))
    for position in row(n):
        pb.loadURDF(urdf, position, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
    try:
        yield lambda: pb.stepSimulation(physicsClientId=client)
    finally:
        pb.disconnect(client)


@contextmanager
def simbot_world(
    n: int, fixed_castors: bool = True, merge_fixed_links: bool = True, full_step: bool = False, moving: bool = False
) -> Iterator[Callable[[], None]]:
    """The empty world and N tugs through simbot's loader; yields a bare step, or `Physics.step`
    (with `moving`, of the kinematic world, 5 ms steps, every tug driven at DRIVE)."""
    world = load_world(asset(f"worlds/{WORLD}.sdf"))
    world = kinematic(world) if moving else world
    physics = Physics(world, fixed_castors=fixed_castors, merge_fixed_links=merge_fixed_links)
    for model in world.models:
        physics.add_model(model)
    robot = load_model(asset("urdf/flexley_tug.sdf"))
    for i, position in enumerate(row(n)):
        physics.add_model(robot, f"tug_{i + 1}", Pose(position))
        if moving:
            physics.drive_base(f"tug_{i + 1}", *DRIVE)
    client = physics.client
    try:
        yield physics.step if full_step else lambda: pb.stepSimulation(physicsClientId=client)
    finally:
        physics.close()


Loop = Callable[[int], AbstractContextManager[Callable[[], None]]]
"""A world of N tugs, yielding its step."""

LOOPS: dict[str, Loop] = {
    "plain": plain_world,
    "lean": simbot_world,
    "step": lambda n: simbot_world(n, full_step=True),
}


def loop_rtf(world: Loop, n: int, seconds: float, step_s: float = STEP_S) -> float:
    """Sim seconds per CPU second of `seconds` of sim time, after the tugs settle on their wheels:
    the loop's own CPU time, as on a machine of its own (wall time here counts others' work too)."""
    with world(n) as step:
        for _ in range(SETTLE_STEPS):
            step()
        steps = round(seconds / step_s)
        start = time.process_time()
        for _ in range(steps):
            step()
        return steps * step_s / (time.process_time() - start)


def kinematic_loop_rtf(n: int, seconds: float) -> float:
    """`loop_rtf` of the kinematic world's `Physics.step`, every tug driven."""
    return loop_rtf(lambda k: simbot_world(k, full_step=True, moving=True), n, seconds, KINEMATIC_STEP_S)


def fleet_tug(folder: Path, imu: bool) -> Path:
    """The Flexley Tug less its cameras (and its IMU unless `imu`), its meshes where they are."""
    text = asset("urdf/flexley_tug.sdf").read_text().replace("../meshes/", f"{asset('meshes')}/")
    kinds = "camera" if imu else "camera|imu"
    text = re.sub(rf'<sensor name="[^"]*" type="(?:{kinds})">.*?</sensor>', "", text, flags=re.DOTALL)
    path = folder / ("tug_imu.sdf" if imu else "tug.sdf")
    path.write_text(text)
    return path


def _ready(node: Node, proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"simbot-server exited with code {proc.returncode} at start")
        try:
            if node.call(f"world/{WORLD}/state", {}, timeout=1.0).get("ok"):
                return
        except (TimeoutError, RuntimeError):
            pass
        time.sleep(0.1)
    raise RuntimeError("the server's world control did not answer within 300 s")


def server_rtf(n: int, mode: str, seconds: float, kinematic: bool = False, imu: bool = True) -> tuple[float, float]:
    """(sim seconds per wall second, per CPU second of the server process) of `simbot-server --robots N
    --mode MODE` over `seconds`, after SETTLE_S (real time first catches up what loading lost)."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{port}"
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as folder:
        command = [sys.executable, "-m", "simbot.sim.server", "--world", WORLD, "--robots", str(n)]
        command += ["--robot", str(fleet_tug(Path(folder), imu)), "--spawn", "0", "0", str(SPAWN_Z), "0"]
        command += ["--mode", mode, "--quiet", "--physics", "kinematic" if kinematic else "dynamic"]
        proc = subprocess.Popen([*command, "--listen", endpoint, "--namespace", namespace], stderr=subprocess.DEVNULL)
        try:
            with Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=180.0), "client") as node:
                _ready(node, proc)
                time.sleep(SETTLE_S)
                sim0, wall0, cpu0 = _sim_time(node), time.perf_counter(), cpu_seconds(proc.pid)
                time.sleep(seconds)
                sim1, wall1, cpu1 = _sim_time(node), time.perf_counter(), cpu_seconds(proc.pid)
            return (sim1 - sim0) / (wall1 - wall0), (sim1 - sim0) / (cpu1 - cpu0)
        finally:
            proc.terminate()
            proc.wait(30)


def _sim_time(node: Node) -> float:
    return float(node.call(f"world/{WORLD}/state", {}, timeout=60.0)["sim_time"])


def dynamic_row(n: int, args: argparse.Namespace) -> tuple[str, float]:
    """The bare loops and the dynamic server with N tugs: the row's cells, and fast mode's sim
    seconds per CPU second (what it would hold on a core of its own)."""
    runs: dict[str, list[float]] = {name: [] for name in LOOPS}
    for _ in range(args.repeats):
        for name, world in LOOPS.items():
            runs[name].append(loop_rtf(world, n, args.seconds))
    rtf = {name: statistics.median(values) for name, values in runs.items()}
    held, _ = server_rtf(n, "realtime", 5 * args.seconds)
    _, fast = server_rtf(n, "fast", 5 * args.seconds)
    cells = (
        f"{rtf['plain']:.3f}× | {rtf['lean']:.3f}× | {rtf['step']:.3f}× | {held:.3f} "
        f"| {fast:.3f}× = {fast / rtf['lean']:.2f} of the loader's loop | {1 / fast:.2f} s"
    )
    return cells, fast


def kinematic_row(n: int, args: argparse.Namespace) -> str:
    held, _ = server_rtf(n, "realtime", 5 * args.seconds, kinematic=True, imu=False)
    _, fast = server_rtf(n, "fast", 5 * args.seconds, kinematic=True, imu=False)
    _, fast_imu = server_rtf(n, "fast", 5 * args.seconds, kinematic=True)
    return f"{held:.3f} | {fast:.2f}×, {1 / fast:.3f} s | {fast_imu:.2f}×, {1 / fast_imu:.3f} s"


READ = 10
"""Tugs whose scans and odometry the goals' client reads (decoded): tug_1..tug_10."""
READ_TOPICS = (("lidar_front", "sensor_msgs/msg/LaserScan"), ("lidar_back", "sensor_msgs/msg/LaserScan"))
ODOM = ("odom", "nav_msgs/msg/Odometry")
SCANS_HZ, ODOM_HZ = 2 * 5.0, 50.0
"""A tug's two lidars at 5 Hz, its odometry at 50 Hz (its SDF)."""
GOAL_SPAWN = ("--spawn", "0", "0", str(SPAWN_Z), "0")
STARTUP_S = 600.0
"""A hundred full tugs on one CPU of a loaded two-core machine load in well under a minute; 200 in two zones too."""


class Reader:
    """A client's subscriptions to the scans and odometry of tug_1..tug_READ, counted once decoded."""

    def __init__(self, node: Node) -> None:
        self._lock = threading.Lock()
        self.scans = self.odom = 0
        for i in range(1, READ + 1):
            for topic, typename in READ_TOPICS:
                node.subscribe(f"tug_{i}/{topic}", typename, self._scan)
            node.subscribe(f"tug_{i}/{ODOM[0]}", ODOM[1], self._odom)

    def _scan(self, _msg: Any) -> None:
        with self._lock:
            self.scans += 1

    def _odom(self, _msg: Any) -> None:
        with self._lock:
            self.odom += 1

    def counts(self) -> tuple[int, int]:
        with self._lock:
            return self.scans, self.odom


@dataclass(frozen=True)
class Held:
    """What a goal run held over its window."""

    tugs: int
    rtf: float
    """The slowest world's sim seconds per wall second."""
    cpu_per_sim_s: float
    """CPU seconds of every process the run started, per sim second (of the slowest world)."""
    scans: float
    odom: float
    """What the client received, per wall second, of READ tugs' scans and odometry."""

    def cells(self, baseline: float) -> str:
        """The row's figures: the bare loop, the factor held and its share of the loop, CPU a tug, messages."""
        per_tug_ms = 1000 * self.cpu_per_sim_s / self.tugs
        expected = self.rtf * READ
        return (
            f"{baseline:.2f}× | {self.rtf:.3f} = {self.rtf / baseline:.2f} of the bare loop | {per_tug_ms:.1f} ms "
            f"| {self.scans:.0f} of {expected * SCANS_HZ:.0f}, {self.odom:.0f} of {expected * ODOM_HZ:.0f}"
        )


def _sim_times(node: Node, worlds: Sequence[str]) -> list[float]:
    return [float(node.call(f"{w}world/{WORLD}/state", {}, timeout=60.0)["sim_time"]) for w in worlds]


def _wait_worlds(node: Node, worlds: Sequence[str], procs: Sequence[subprocess.Popen[bytes]]) -> None:
    """Until each world's state answers; RuntimeError if a process exits first."""
    deadline = time.monotonic() + STARTUP_S
    for world in worlds:
        while True:
            if any(p.poll() is not None for p in procs):
                raise RuntimeError(f"a process exited with code {[p.poll() for p in procs]} at start")
            if time.monotonic() > deadline:
                raise RuntimeError(f"{world}world/{WORLD}/state did not answer within {STARTUP_S:g} s")
            try:
                if node.call(f"{world}world/{WORLD}/state", {}, timeout=2.0).get("ok"):
                    break
            except (TimeoutError, RuntimeError):
                time.sleep(0.2)


def held(node: Node, worlds: Sequence[str], pids: Sequence[int], tugs: int, seconds: float) -> Held:
    """After SETTLE_S, `seconds` of wall time: the worlds' sim time, the processes' CPU, the client's messages."""
    reader = Reader(node)
    time.sleep(SETTLE_S)
    sim0, wall0, cpu0, got0 = _sim_times(node, worlds), time.perf_counter(), _cpu(pids), reader.counts()
    time.sleep(seconds)
    sim1, wall1, cpu1, got1 = _sim_times(node, worlds), time.perf_counter(), _cpu(pids), reader.counts()
    wall, sim = wall1 - wall0, min(b - a for a, b in zip(sim0, sim1, strict=True))
    scans, odom = ((b - a) / wall for a, b in zip(got0, got1, strict=True))
    return Held(tugs, sim / wall, (cpu1 - cpu0) / sim, scans, odom)


def _cpu(pids: Sequence[int]) -> float:
    return sum(cpu_seconds(pid) for pid in pids)


def one_core(n: int, moving: bool, seconds: float) -> Held:
    """`simbot-server --robots N`, the full tug, real time, pinned to this process's last CPU."""
    return one_server(n, moving, seconds, ["taskset", "-c", str(max(os.sched_getaffinity(0)))])


def both_cores(n: int, moving: bool, seconds: float) -> Held:
    """`simbot-server --robots N`, the full tug, real time, on every core."""
    return one_server(n, moving, seconds, [])


def one_server(n: int, moving: bool, seconds: float, pinned: list[str]) -> Held:
    """`simbot-server --robots N`, the full tug, real time, run under `pinned` (a `taskset`, or nothing)."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{port}"
    command = [*pinned, sys.executable, "-m", "simbot.sim.server", "--world", WORLD]
    command += ["--robots", str(n), *GOAL_SPAWN, "--quiet", "--physics", "kinematic" if moving else "dynamic"]
    proc = subprocess.Popen([*command, "--listen", endpoint, "--namespace", namespace], stderr=subprocess.DEVNULL)
    try:
        with Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=STARTUP_S), "client") as node:
            _wait_worlds(node, [""], [proc])
            return held(node, [""], [proc.pid], n, seconds)
    finally:
        stop(proc)


def two_zones(n: int, moving: bool, seconds: float) -> Held:
    """`simbot launch --zones 2` of N full tugs, real time, on every core; CPU counted for the zone
    servers, launch (its router) and the handover."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{port}"
    fleet = f"--robots {n} {' '.join(GOAL_SPAWN)} --quiet --physics {'kinematic' if moving else 'dynamic'}"
    command = [sys.executable, "-m", "simbot.clients.launch", "--world", WORLD, "--zones", "2", "--clients", ""]
    command += [f"--server-args={fleet}", "--listen", endpoint, "--namespace", namespace]
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT)
        try:
            with Node(
                BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=STARTUP_S), "client"
            ) as node:
                worlds = ["zone_1/", "zone_2/"]
                _wait_worlds(node, worlds, [proc])
                pids = _started(out, proc, "handover")
                return held(node, worlds, [proc.pid, *pids.values()], n, seconds)
        finally:
            stop(proc)


def _started(out: Any, proc: subprocess.Popen[bytes], last: str) -> dict[str, int]:
    """The pids of what launch started (its `started NAME (pid N)` lines), once it has started `last`."""
    deadline = time.monotonic() + STARTUP_S
    while time.monotonic() < deadline and proc.poll() is None:
        out.seek(0)
        pids = {m[1]: int(m[2]) for m in re.finditer(rb"\[launch\] started (\w+) \(pid (\d+)\)", out.read())}
        if last.encode() in pids:
            return {name.decode(): pid for name, pid in pids.items()}
        time.sleep(0.2)
    raise RuntimeError(f"launch did not start {last}")


GOALS = (
    ("100 kinematic tugs, one core", 100, True, one_core, "≥ 1.0; ≤ 5 ms (issue 48)"),
    ("200 kinematic tugs, two zones, both cores", 200, True, two_zones, "≥ 1.0 (issue 48)"),
    ("500 kinematic tugs, one core", 500, True, one_core, "≥ 0.98 (issue 58)"),
    ("1000 kinematic tugs, both cores", 1000, True, both_cores, "≥ 0.98; ≤ 0.8 ms (issue 58)"),
    ("10 dynamic tugs, one core", 10, False, one_core, "≥ 1.0 (issue 48)"),
    ("20 dynamic tugs, two zones, both cores", 20, False, two_zones, "≥ 0.98 (issue 58)"),
)


def bare_loop(n: int, moving: bool, seconds: float) -> float:
    """The goal's baseline: the kinematic world's `Physics.step`, or the loader's bare loop."""
    return kinematic_loop_rtf(n, seconds) if moving else loop_rtf(simbot_world, n, seconds)


def goal_rows(args: argparse.Namespace) -> list[str]:
    """Issues 48's and 58's goals, each against the bare loop of the same tugs in this run."""
    table = ["| goal run (full tugs, real time) | bare loop, same tugs: per CPU second | factor held | CPU per tug "
             "per sim second | client got, per second: scans, odometry of 10 tugs | goal (factor; CPU) |",
             "| --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    for label, n, moving, run, goal in GOALS:
        loops = [bare_loop(n, moving, args.seconds) for _ in range(args.repeats)]
        table.append(f"| {label} | {run(n, moving, 5 * args.seconds).cells(statistics.median(loops))} | {goal} |")
        print(table[-1], flush=True)
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleets", default="1,10,20,50,100", help="the numbers of tugs, comma-separated")
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="sim seconds per bare loop; a server runs 5× as long"
    )
    parser.add_argument("--repeats", type=int, default=3, help="runs of each bare loop (median)")
    parser.add_argument("--kinematic-only", action="store_true", help="the kinematic servers alone")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--goals-only", action="store_true", help="the goal runs alone, not the table by N")
    which.add_argument("--no-goals", action="store_true", help="the table by N alone")
    args = parser.parse_args()
    table = ["| tugs | dynamic: plain URDF, bare loop | loader's bare loop | `Physics.step` | server, real time: "
          "factor held | server fast, per CPU second | CPU per sim second | kinematic server, real time: "
          "factor held | kinematic fast, per CPU second; CPU per sim second | the same with IMUs at 200 Hz |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    dynamic = not args.kinematic_only
    for n in () if args.goals_only else (int(part) for part in args.fleets.split(",")):
        cells = "— | — | — | — | — | —"
        if dynamic:
            cells, fast = dynamic_row(n, args)
            dynamic = fast >= 0.5
        table.append(f"| {n} | {cells} | {kinematic_row(n, args)} |")
        print(table[-1], flush=True)
    lines = [] if args.goals_only else table
    if not args.no_goals:
        lines += ([""] if lines else []) + goal_rows(args)
    publish("fleet", lines)


if __name__ == "__main__":
    main()
