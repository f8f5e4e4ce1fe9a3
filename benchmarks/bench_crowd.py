"""Benchmark of the crowd: what ten people walking by the social-force model (SocialForce) cost the
server per step against ten walking their scripts, in one run.

Two servers built in this process exactly as `simbot-server` builds them (`Server`, lockstep, a
real Zenoh session): the warehouse with the Flexley Tug standing (its lidars, IMU, odometry, tf,
poses and clock running; cameras idle) and `--actors` workers created through world control, each
on bench_actors' 4 m beat, a row of them 1 m apart: in one server they walk their scripts (the
Actors system), in the other each has a SocialForce `<plugin>` (every person reads the others, the
tug and the warehouse's racks at every step). Each server steps `--steps` steps at a time, the two
interleaved `--repeats` times; the figure is the median milliseconds per step of each, and their
ratio. Camera frames are not measured here: a crowd-driven person is drawn as a scripted one is.

    python benchmarks/bench_crowd.py [--actors N] [--steps S] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

from bench_actors import ACTOR, MESHES, ms_per_step
from bench_server import free_port
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.resources import asset
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world_control import create_request
from simbot.sim.server import Server, ServerConfig, world_path

PLUGIN = '<plugin name="simbot::systems::SocialForce" filename="simbot-social-force-system"/>'


@contextmanager
def server(actors: int, crowd: bool) -> Iterator[Server]:
    """The warehouse and the tug in lockstep, with `actors` workers, crowd-driven or scripted."""
    options = BusOptions(listen=(f"tcp/127.0.0.1:{free_port()}",), namespace=f"bench_{uuid.uuid4().hex[:8]}")
    config = ServerConfig(world_path("warehouse"), asset("urdf/flexley_tug.sdf"), (-2.5, 0.0, 0.1, 0.0), Mode.LOCKSTEP)
    with Node(options, "server") as node:
        built = Server(config, node)
        try:
            for index in range(actors):
                text = ACTOR.format(
                    index=index, x=-6.0 + index, y=2.5 + (index % 2), skin=MESHES / "worker.dae", animation=""
                )
                built.world.create(
                    create_request({"sdf": text.replace("</actor>", PLUGIN + "</actor>") if crowd else text})
                )
            yield built
        finally:
            built.close()


def step_costs(actors: int, steps: int, repeats: int) -> tuple[float, float]:
    """Median ms per step: `actors` scripted workers, the same crowd-driven."""
    runs: tuple[list[float], list[float]] = ([], [])
    with server(actors, crowd=False) as scripted, server(actors, crowd=True) as crowd:
        built = (scripted, crowd)
        for one in built:  # past the first steps' one-off costs
            ms_per_step(one, 200)
        for _ in range(repeats):
            for one, figures in zip(built, runs, strict=True):
                figures.append(ms_per_step(one, steps))
    return statistics.median(runs[0]), statistics.median(runs[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scripted, crowd = step_costs(args.actors, args.steps, args.repeats)
    table = [
        f"| warehouse, tug standing, {args.actors} workers | ms per server step | ratio |",
        "| --- | --- | --- |",
        f"| walking their scripts (Actors) | {scripted:.3f} | 1.00 |",
        f"| crowd-driven (SocialForce) | {crowd:.3f} | {crowd / scripted:.2f} |",
    ]
    publish("crowd", table)


if __name__ == "__main__":
    main()
