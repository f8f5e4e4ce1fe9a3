"""Benchmark of the crowd: what ten people walking by the social-force model (SocialForce) cost the
server per step against ten walking their scripts, in one run.

Four servers built in this process exactly as `simbot-server` builds them (`Server`, lockstep, a
real Zenoh session): the warehouse with the Flexley Tug standing (its lidars, IMU, odometry, tf,
poses and clock running; cameras idle) and `--actors` workers created through world control, each
on bench_actors' 4 m beat, a row of them 1 m apart: in one server they walk their scripts (the
Actors system), in the others each has a SocialForce `<plugin>` with its forces from the others,
the tug and the warehouse's racks updated at one of RATES (its default every 20 ms, every 10 ms,
every 1 ms step), the position at every step. Each server steps `--steps` steps at a time, the
four interleaved `--repeats` times; the figure is the median milliseconds per step of each, their
ratio to the scripted, and the crowd's own cost per person per step (the difference over the
number of people). Camera frames are not measured here: a crowd-driven person is drawn as a
scripted one is.

    python benchmarks/bench_crowd.py [--actors N] [--steps S] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import uuid
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager

from bench_actors import ACTOR, MESHES, ms_per_step
from bench_server import free_port
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.resources import asset
from simbot.sim.kit.social_force import Crowd
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world_control import create_request
from simbot.sim.server import Server, ServerConfig, world_path

PLUGIN = '<plugin name="simbot::systems::SocialForce" filename="simbot-social-force-system">{}</plugin>'
RATES = (Crowd().update_rate, 100.0, 1000.0)
"""Hz: the plugin's forces updated at its default, every 10 ms and at every 1 ms step."""


@contextmanager
def server(actors: int, crowd: str | None) -> Iterator[Server]:
    """The warehouse and the tug in lockstep, with `actors` workers, scripted or crowd-driven (the
    plugin's parameters `crowd`)."""
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
                    create_request(
                        {"sdf": text if crowd is None else text.replace("</actor>", PLUGIN.format(crowd) + "</actor>")}
                    )
                )
            yield built
        finally:
            built.close()


def step_costs(actors: int, steps: int, repeats: int) -> list[float]:
    """Median ms per step: `actors` scripted workers, then the same crowd-driven at each of RATES."""
    configs = [None, *(f"<update_rate>{rate:g}</update_rate>" for rate in RATES)]
    runs: list[list[float]] = [[] for _ in configs]
    with ExitStack() as stack:
        built = [stack.enter_context(server(actors, crowd)) for crowd in configs]
        for one in built:  # past the first steps' one-off costs
            ms_per_step(one, 200)
        for _ in range(repeats):
            for one, figures in zip(built, runs, strict=True):
                figures.append(ms_per_step(one, steps))
    return [statistics.median(figures) for figures in runs]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scripted, *crowd = step_costs(args.actors, args.steps, args.repeats)
    table = [
        f"| warehouse, tug standing, {args.actors} workers | ms per server step | ratio | ms per person per step over scripted |",
        "| --- | --- | --- | --- |",
        f"| walking their scripts (Actors) | {scripted:.3f} | 1.00 | — |",
        *(
            f"| crowd-driven (SocialForce), forces every {1000 / rate:g} ms{' (default)' * (i == 0)} | {ms:.3f} | "
            f"{ms / scripted:.2f} | {(ms - scripted) / args.actors:.3f} |"
            for i, (rate, ms) in enumerate(zip(RATES, crowd, strict=True))
        ),
    ]
    publish("crowd", table)


if __name__ == "__main__":
    main()
