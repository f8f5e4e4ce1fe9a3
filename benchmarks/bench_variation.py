"""Benchmark of randomised worlds (simbot.variation): a seeded reset of the warehouse with its people
against a plain reset of the same world, in one run on one in-process lockstep server.

Each round times, in wall-clock seconds: drawing a variant alone (`vary`: the sun, the textures,
the clutter's places); a plain reset (`{"reset": {"all": true}}`: the world back as it started);
a seeded reset (`{"reset": {"seed": n}}`: every model and system out, the variant's in); and each
reset followed by the front camera's first frame (the render workers take the new world: restarted
after a seeded reset). Plain and seeded alternate; a figure is the median over the rounds.

    python benchmarks/bench_variation.py [--rounds R]
"""

from __future__ import annotations

import argparse
import functools
import statistics
import sys
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.additions import addition_path
from simbot.description.resources import asset
from simbot.sim.loop.simulation import Mode
from simbot.sim.server import Server, ServerConfig, world_path

CAMERA = "camera_front"
FRAME_TIMEOUT_S = 120.0


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
    first_frame(server, got)  # the render workers up once before the rounds
    for seed in range(count):
        figures["draw"].append(timed(functools.partial(variations.draw, seed)))
        figures["plain"].append(timed(server.world.reset))
        figures["plain_frame"].append(timed(functools.partial(first_frame, server, got)))
        figures["seeded"].append(timed(functools.partial(server.world.reset, seed)))
        figures["seeded_frame"].append(timed(functools.partial(first_frame, server, got)))
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
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
                figures = rounds(server, got, args.rounds)
        finally:
            server.close()
    median = {name: statistics.median(values) for name, values in figures.items()}
    table = [
        f"| the warehouse with its people, tug with six 640×480 cameras (median of {args.rounds} rounds) | wall time | ÷ plain |",
        "| --- | --- | --- |",
        f"| draw a variant (`vary`) | {median['draw'] * 1e3:.0f} ms | — |",
        f"| plain reset | {median['plain'] * 1e3:.1f} ms | 1 |",
        f"| seeded reset | {median['seeded'] * 1e3:.0f} ms | {median['seeded'] / median['plain']:.0f}× |",
        f"| plain reset, then the front camera's first frame | {median['plain'] + median['plain_frame']:.2f} s | 1 |",
        f"| seeded reset, then the front camera's first frame | {median['seeded'] + median['seeded_frame']:.2f} s "
        f"| {(median['seeded'] + median['seeded_frame']) / (median['plain'] + median['plain_frame']):.1f}× |",
    ]
    publish("variation", table)


if __name__ == "__main__":
    main()
