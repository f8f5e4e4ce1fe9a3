"""Benchmark of the crowd: what ten people walking by the social-force model (SocialForce) cost the
server per step against ten walking their scripts, in one run.

Two servers built in this process exactly as `simbot-server` builds them (`Server`, lockstep, a
real Zenoh session): the warehouse with the Flexley Tug standing (its lidars, IMU, odometry, tf,
poses and clock running; cameras idle) and `--actors` workers created through world control, each
on bench_actors' 4 m beat, a row of them 1 m apart: in one server they walk their scripts (the
Actors system), in the second each has a SocialForce `<plugin>` at its defaults (the forces from
the others, the tug and the warehouse's racks every 10 ms, the position at every step), in the
third the same with `<update_rate>1000</update_rate>` (the forces at every step). Each server steps
`--steps` steps at a time, the three interleaved `--repeats` times; the figure is the median
milliseconds per step of each, their ratio to the scripted, and the crowd's own cost per person
per step (the difference over the number of people). Camera frames are not measured here: a
crowd-driven person is drawn as a scripted one is.

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

PLUGIN = '<plugin name="simbot::systems::SocialForce" filename="simbot-social-force-system">{}</plugin>'
EVERY_STEP = "<update_rate>1000</update_rate>"


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


def step_costs(actors: int, steps: int, repeats: int) -> tuple[float, float, float]:
    """Median ms per step: `actors` scripted workers, the same crowd-driven, and with the forces at every step."""
    runs: tuple[list[float], list[float], list[float]] = ([], [], [])
    with server(actors, None) as scripted, server(actors, "") as crowd, server(actors, EVERY_STEP) as every:
        built = (scripted, crowd, every)
        for one in built:  # past the first steps' one-off costs
            ms_per_step(one, 200)
        for _ in range(repeats):
            for one, figures in zip(built, runs, strict=True):
                figures.append(ms_per_step(one, steps))
    return statistics.median(runs[0]), statistics.median(runs[1]), statistics.median(runs[2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scripted, crowd, every = step_costs(args.actors, args.steps, args.repeats)
    table = [
        f"| warehouse, tug standing, {args.actors} workers | ms per server step | ratio | ms per person per step over scripted |",
        "| --- | --- | --- | --- |",
        f"| walking their scripts (Actors) | {scripted:.3f} | 1.00 | — |",
        *(
            f"| crowd-driven (SocialForce), {what} | {ms:.3f} | {ms / scripted:.2f} | {(ms - scripted) / args.actors:.3f} |"
            for what, ms in (("forces every 10 ms (default)", crowd), ("forces every step", every))
        ),
    ]
    publish("crowd", table)


if __name__ == "__main__":
    main()
