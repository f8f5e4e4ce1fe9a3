"""Benchmark of randomised worlds (simbot.variation): a seeded reset of the warehouse with its people
applied in place, against a plain reset of the same world; a dataset over many seeds against one
world's; a render worker's start. Ratios against baselines measured in the same run.

- Resets, on one in-process lockstep server (the tug's six 640×480 cameras): drawing a variant
  alone (`vary`); a plain reset (`{"reset": {"all": true}}`: the world back as it started); a seeded
  reset (`{"reset": {"seed": n}}`: the variant applied in place, simbot.sim.loop.world_edit); each
  followed by the front camera's first frame (the render workers take the edit). Plain and seeded
  alternate, seeds 0, 1, 2, ...; a figure is the median over the rounds.
- A render worker's start: a pool of one worker and the front camera on the same scene, from its
  creation to its first frame, with the fork server up (simbot.sim.render.starter) and the
  textures' mip chains cached (as every pool after a server's first).
- Datasets (`--sets N`): `simbot dataset` on a lockstep `simbot-server` (the warehouse with its
  people, the six cameras), stepped from here until the client is done: N sets of one world
  (`--count N`) against one set of each of N worlds (`--randomise 0:N --count 1`).

    python benchmarks/bench_variation.py [--rounds R] [--sets N]
"""

from __future__ import annotations

import argparse
import functools
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port
from live_runs import connect, wait_ready
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.additions import addition_path
from simbot.description.resources import asset
from simbot.sim.loop.simulation import Mode
from simbot.sim.render import BodyState, RenderPool
from simbot.sim.server import Server, ServerConfig, world_path

CAMERA = "camera_front"
FRAME_TIMEOUT_S = 120.0
DATASET_TIMEOUT_S = 1800.0
STEPS = 50
"""Steps of each world-control call that advances the dataset's lockstep world."""


def timed(work: Callable[[], object]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def first_frame(server: Server, got: threading.Event) -> None:
    """Steps until the front camera's next frame (its first after a reset) is in."""
    got.clear()
    deadline = time.monotonic() + FRAME_TIMEOUT_S
    while not got.is_set():
        if time.monotonic() > deadline:
            raise SystemExit(f"no {CAMERA} frame within {FRAME_TIMEOUT_S} s")
        server.sim.step()
        got.wait(0.01)


def rounds(server: Server, got: threading.Event, count: int) -> dict[str, list[float]]:
    """Plain and seeded resets, alternating, each alone and then with the first frame after it."""
    variations = server.world.variations
    assert variations is not None, "the warehouse has its own profile"
    figures: dict[str, list[float]] = {"draw": [], "plain": [], "seeded": [], "plain_frame": [], "seeded_frame": []}
    figures["start"] = [timed(functools.partial(first_frame, server, got))]  # the fork server and the workers up
    for seed in range(count):
        figures["draw"].append(timed(functools.partial(variations.draw, seed)))
        figures["plain"].append(timed(server.world.reset))
        figures["plain_frame"].append(timed(functools.partial(first_frame, server, got)))
        figures["seeded"].append(timed(functools.partial(server.world.reset, seed)))
        figures["seeded_frame"].append(timed(functools.partial(first_frame, server, got)))
    return figures


def worker_starts(server: Server, count: int) -> list[float]:
    """A pool of one worker on the running scene, its creation to the front camera's first frame."""
    rendering = next(s for s in server.world.systems if type(s).__name__ == "Rendering")
    physics = server.world.physics
    bodies = [rendering._scene_body(name) for name in rendering._order(physics.body_names())]  # type: ignore[attr-defined]
    camera = next(c for c in rendering.cameras if c.spec.name == CAMERA)  # type: ignore[attr-defined]
    states = {name: BodyState(*physics.body_state(name)) for name in physics.moving_bodies()}
    pose = physics.frame_pose(*camera.where)
    seconds = []
    for _ in range(count):
        start = time.perf_counter()
        with RenderPool(bodies, [camera.spec], workers=1, light=rendering.light) as pool:  # type: ignore[attr-defined]
            pool.request(0, 1, pose, states)
            pool.collect(wait_for=0, timeout=FRAME_TIMEOUT_S)
            seconds.append(time.perf_counter() - start)
    return seconds


def in_process(count: int) -> tuple[dict[str, list[float]], list[float]]:
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    config = ServerConfig(
        world_path("warehouse"),
        asset("urdf/flexley_tug.sdf"),
        mode=Mode.LOCKSTEP,
        overrides={"camera.size": (640, 480)},
        additions=(addition_path("warehouse_people"),),
    )
    got = threading.Event()
    with Node(BusOptions(listen=(endpoint,), namespace=namespace), "server") as node:
        server = Server(config, node)
        try:
            with Node(BusOptions(connect=(endpoint,), namespace=namespace), "client") as client:
                client.subscribe(CAMERA, "sensor_msgs/msg/Image", lambda _msg: got.set())
                figures = rounds(server, got, count)
                return figures, worker_starts(server, count)
        finally:
            server.close()


def dataset_seconds(sets: int, randomise: bool) -> float:
    """Wall seconds of `simbot dataset` writing `sets` sets (one world, or one of each of `sets` worlds)."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    world = ["--world", "warehouse", "--add", "warehouse_people", "--mode", "lockstep", "--quiet"]
    bus = ["--connect", endpoint, "--namespace", namespace]
    server = subprocess.Popen(
        [sys.executable, "-m", "simbot.sim.server", *world, "--listen", endpoint, "--namespace", namespace],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        with (
            connect(endpoint, namespace, server) as node,
            tempfile.TemporaryDirectory() as out,
            tempfile.TemporaryFile() as log,
        ):
            wait_ready(node)
            seeds = ["--randomise", f"0:{sets}", "--count", "1"] if randomise else ["--count", str(sets)]
            command = [sys.executable, "-m", "simbot.cli", "dataset", "--out", out, *bus, *seeds]
            start = time.perf_counter()
            client = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=log)
            stepping = threading.Thread(target=_step_while, args=(node, client), daemon=True)
            stepping.start()
            try:
                client.wait(DATASET_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                client.kill()
                raise SystemExit(f"the dataset client did not finish within {DATASET_TIMEOUT_S:.0f} s") from None
            seconds = time.perf_counter() - start  # the client's own time: not the step it left unfinished
            stepping.join()
            if client.returncode != 0:
                log.seek(0)
                raise SystemExit(f"simbot dataset exited with {client.returncode}: {log.read().decode()[-500:]}")
            return seconds
    finally:
        server.terminate()
        server.wait(30)


def _step_while(node: Node, client: subprocess.Popen[bytes]) -> None:
    """Advances the lockstep world while the client runs (the step the client leaves behind waits for
    its workers' subscribers to go: simbot.sim.render.publishing, MATCH_TIMEOUT_S)."""
    while client.poll() is None:
        node.call("world/warehouse/control", {"multi_step": STEPS}, timeout=FRAME_TIMEOUT_S)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--sets", type=int, default=100)
    args = parser.parse_args()
    figures, starts = in_process(args.rounds)
    one_world = dataset_seconds(args.sets, randomise=False)
    many_worlds = dataset_seconds(args.sets, randomise=True)
    m = {name: statistics.median(values) for name, values in figures.items()}
    plain_frame, seeded_frame = m["plain"] + m["plain_frame"], m["seeded"] + m["seeded_frame"]
    table = [
        f"| the warehouse with its people, tug with six 640×480 cameras (median of {args.rounds} rounds) | wall time | ratio |",
        "| --- | --- | --- |",
        f"| draw a variant (`vary`) | {m['draw'] * 1e3:.0f} ms | — |",
        f"| plain reset | {m['plain'] * 1e3:.1f} ms | 1 |",
        f"| seeded reset, applied in place | {m['seeded'] * 1e3:.0f} ms | {m['seeded'] / m['plain']:.0f}× plain |",
        f"| plain reset, then the front camera's first frame | {plain_frame:.2f} s | 1 |",
        f"| seeded reset, then the front camera's first frame | {seeded_frame:.2f} s | {seeded_frame / plain_frame:.1f}× plain |",
        f"| a render worker's start to its first frame (fork server up, textures cached; median of {args.rounds}) "
        f"| {statistics.median(starts):.2f} s | — |",
        f"| the server's first frame (fork server and two workers started) | {m['start']:.2f} s | — |",
        f"| `simbot dataset --count {args.sets}`: {args.sets} sets of one world | {one_world:.1f} s | 1 |",
        f"| `simbot dataset --randomise 0:{args.sets} --count 1`: a set of each of {args.sets} worlds "
        f"| {many_worlds:.1f} s | {many_worlds / one_world:.2f}× one world |",
    ]
    publish("variation", table)


if __name__ == "__main__":
    main()
