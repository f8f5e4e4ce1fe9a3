"""Benchmark of a fleet: N Flexley Tugs in a row in one world, N = 1, 5, 10, 20.

Every figure is a ratio against a baseline measured in the same run, the variants interleaved and
each the median of `--repeats` runs (a shared machine is noisy); the bare loops count their own
CPU time, the servers wall time (what real time means):

1. baseline: a bare PyBullet loop at 1 kHz, the plain URDF (`urdf/flexley_tug.urdf`, 20 joints,
   12 of them castor gimbals) loaded N times by `loadURDF` on a plane, nothing but `stepSimulation`;
2. simbot's loader with the castors' gimbals: the same loop over the bodies `Physics.add_model`
   builds with `fixed_castors=False, merge_fixed_links=False` (passive joints, SDF friction, tyre
   compliance, castors frictionless and contact-free until they touch);
3. with `fixed_castors` alone (each ball castor one rigid frictionless sphere);
4. simbot's loader as it is (castors fixed, fixed links merged: 5 links a tug);
5. `Physics.step`: simbot's loader plus its wheel-friction model, what the server steps;
6. `simbot-server` in real time and in fast mode with N tugs (two lidars and an IMU each publishing,
   cameras idle: nobody subscribes), measured through world control's sim time: the real-time
   factor it holds (wall time, on this machine as loaded as it is) and fast mode's sim seconds per
   CPU second of the server process (what it would hold on a core of its own; ≥ 1 is real time). The tugs' SDF
   states its topics, so all N publish on the same keys: a measure of rate, not of a fleet's bus.

    python benchmarks/bench_fleet.py [--fleets 1,5,10,20] [--seconds S] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

from bench_sensors import cpu_seconds
from bench_server import free_port

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
    "gimbals": lambda n: simbot_world(n, fixed_castors=False, merge_fixed_links=False),
    "fixed": lambda n: simbot_world(n, merge_fixed_links=False),
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


def fleet_world(folder: Path, n: int) -> Path:
    """The empty world with tugs 2..N included beside the server's own robot (spawned at the row's start)."""
    tug = asset("urdf/flexley_tug.sdf")
    includes = "".join(
        f"<include><uri>{tug}</uri><name>tug_{i + 1}</name><pose>{x} {y} {z} 0 0 0</pose></include>"
        for i, (x, y, z) in enumerate(row(n))
        if i > 0
    )
    path = folder / f"fleet_{n}.sdf"
    path.write_text(asset(f"worlds/{WORLD}.sdf").read_text().replace("</world>", includes + "</world>"))
    return path


def _ready(node: Node, proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"simbot-server exited with code {proc.returncode} at start")
        try:
            if node.call(f"world/{WORLD}/state", {}, timeout=1.0).get("ok"):
                return
        except (TimeoutError, RuntimeError):
            pass
        time.sleep(0.1)
    raise RuntimeError("the server's world control did not answer within 120 s")


def server_rtf(n: int, mode: str, seconds: float) -> tuple[float, float]:
    """(sim seconds per wall second, per CPU second of the server process) of `simbot-server --mode
    MODE` with N tugs over `seconds`, after SETTLE_S (real time first catches up what loading lost)."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{port}"
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as folder:
        command = [sys.executable, "-m", "simbot.sim.server", "--world", str(fleet_world(Path(folder), n))]
        command += ["--spawn", "0", "0", str(SPAWN_Z), "0", "--mode", mode, "--quiet"]
        proc = subprocess.Popen([*command, "--listen", endpoint, "--namespace", namespace], stderr=subprocess.DEVNULL)
        try:
            with Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=30.0), "client") as node:
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
    return float(node.call(f"world/{WORLD}/state", {})["sim_time"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleets", default="1,5,10,20", help="the numbers of tugs, comma-separated")
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="sim seconds per bare loop; a server runs 5× as long"
    )
    parser.add_argument("--repeats", type=int, default=5, help="runs of each bare loop (median)")
    parser.add_argument("--no-server", action="store_true", help="the bare loops only")
    args = parser.parse_args()
    print("| tugs | plain URDF, bare loop | cost per tug ÷ the first row's | loader, gimbals / plain "
          "| castors fixed / plain | loader (fixed, merged) / plain | Physics.step / plain "
          "| server real time: factor held | server fast, per CPU second |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    one_tug = None
    for n in (int(part) for part in args.fleets.split(",")):
        runs: dict[str, list[float]] = {name: [] for name in LOOPS}
        for _ in range(args.repeats):
            for name, world in LOOPS.items():
                runs[name].append(loop_rtf(world, n, args.seconds))
        rtf = {name: statistics.median(values) for name, values in runs.items()}
        one_tug = one_tug or rtf["plain"] * n
        server = "| — | — |"
        if not args.no_server:
            held, _ = server_rtf(n, "realtime", 5 * args.seconds)
            _, fast = server_rtf(n, "fast", 5 * args.seconds)
            server = f"| {held:.3f} | {fast:.2f}× = {fast / rtf['plain']:.2f} plain |"
        print(
            f"| {n} | {rtf['plain']:.2f}× real time | {one_tug / (rtf['plain'] * n):.2f} "
            f"| {rtf['gimbals'] / rtf['plain']:.2f} | {rtf['fixed'] / rtf['plain']:.2f} "
            f"| {rtf['lean'] / rtf['plain']:.2f} | {rtf['step'] / rtf['plain']:.2f} {server}",
            flush=True,
        )


if __name__ == "__main__":
    main()
