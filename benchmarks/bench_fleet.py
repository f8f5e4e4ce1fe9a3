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

    python benchmarks/bench_fleet.py [--fleets 1,10,20,50,100] [--seconds S] [--repeats R] [--kinematic-only]
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

from bench_server import free_port
from live_runs import cpu_seconds
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description import load_model, load_world
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.bullet import pb
from simbot.sim.physics import Physics

STEP_S = 0.001
SPACING_M = 1.0
"""Tugs side by side along y, 0.5 m apart (the chassis is 0.5 m wide)."""
SPAWN_Z = 0.1
SETTLE_STEPS = 300
SETTLE_S = 2.0
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
    n: int, fixed_castors: bool = True, merge_fixed_links: bool = True, full_step: bool = False
) -> Iterator[Callable[[], None]]:
    """The empty world and N tugs through simbot's loader; yields a bare step, or `Physics.step`."""
    world = load_world(asset(f"worlds/{WORLD}.sdf"))
    physics = Physics(world, fixed_castors=fixed_castors, merge_fixed_links=merge_fixed_links)
    for model in world.models:
        physics.add_model(model)
    robot = load_model(asset("urdf/flexley_tug.sdf"))
    for i, position in enumerate(row(n)):
        physics.add_model(robot, f"tug_{i + 1}", Pose(position))
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


def loop_rtf(world: Loop, n: int, seconds: float) -> float:
    """Sim seconds per CPU second of `seconds` of sim time, after the tugs settle on their wheels:
    the loop's own CPU time, as on a machine of its own (wall time here counts others' work too)."""
    with world(n) as step:
        for _ in range(SETTLE_STEPS):
            step()
        steps = round(seconds / STEP_S)
        start = time.process_time()
        for _ in range(steps):
            step()
        return steps * STEP_S / (time.process_time() - start)


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleets", default="1,10,20,50,100", help="the numbers of tugs, comma-separated")
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="sim seconds per bare loop; a server runs 5× as long"
    )
    parser.add_argument("--repeats", type=int, default=3, help="runs of each bare loop (median)")
    parser.add_argument("--kinematic-only", action="store_true", help="the kinematic servers alone")
    args = parser.parse_args()
    table = ["| tugs | dynamic: plain URDF, bare loop | loader's bare loop | `Physics.step` | server, real time: "
          "factor held | server fast, per CPU second | CPU per sim second | kinematic server, real time: "
          "factor held | kinematic fast, per CPU second; CPU per sim second | the same with IMUs at 200 Hz |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    dynamic = not args.kinematic_only
    for n in (int(part) for part in args.fleets.split(",")):
        cells = "— | — | — | — | — | —"
        if dynamic:
            cells, fast = dynamic_row(n, args)
            dynamic = fast >= 0.5
        table.append(f"| {n} | {cells} | {kinematic_row(n, args)} |")
        print(table[-1], flush=True)
    publish("fleet", table)


if __name__ == "__main__":
    main()
