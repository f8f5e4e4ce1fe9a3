"""Benchmark of actors: what ten walking actors cost the server per step, against the same world without them.

One run, two servers built in this process exactly as `simbot-server` builds them (`Server`,
lockstep, a real Zenoh session): the warehouse with the Flexley Tug standing (its lidars, IMU,
odometry, tf, poses and clock running; cameras idle), and the same with ten actors created through
world control, each walking a 4 m loop at 1 m/s (their skins Fuel files not in the cache, so each
is its proxy: a kinematic capsule the lidars see and the physics collides with). Each server steps
`--steps` steps at a time, the two interleaved `--repeats` times; the figure is the median
milliseconds per step of each, and their ratio (a shared machine is noisy: the median of
interleaved runs holds where single runs do not).

    python benchmarks/bench_actors.py [--actors N] [--steps S] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

from bench_server import free_port
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.resources import asset
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world_control import create_request
from simbot.sim.server import Server, ServerConfig, world_path

ACTOR = """<?xml version="1.0"?>
<sdf version="1.9">
  <actor name="walker_{index}">
    <pose>{x} {y} 1 0 0 0</pose>
    <skin><filename>https://fuel.gazebosim.org/1.0/Mingfei/models/actor/tip/files/meshes/walk.dae</filename></skin>
    <script><trajectory id="0" type="walk">
      <waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint>
      <waypoint><time>2</time><pose>2 0 0 0 0 0</pose></waypoint>
      <waypoint><time>2.5</time><pose>2 0 0 0 0 3.14159</pose></waypoint>
      <waypoint><time>4.5</time><pose>0 0 0 0 0 3.14159</pose></waypoint>
      <waypoint><time>5</time><pose>0 0 0 0 0 0</pose></waypoint>
    </trajectory></script>
  </actor>
</sdf>
"""


@contextmanager
def server(actors: int) -> Iterator[Server]:
    """The warehouse and the tug in lockstep, with `actors` walkers created in a row 1 m apart."""
    options = BusOptions(listen=(f"tcp/127.0.0.1:{free_port()}",), namespace=f"bench_{uuid.uuid4().hex[:8]}")
    config = ServerConfig(world_path("warehouse"), asset("urdf/flexley_tug.sdf"), (-2.5, 0.0, 0.1, 0.0), Mode.LOCKSTEP)
    with Node(options, "server") as node:
        built = Server(config, node)
        try:
            for index in range(actors):
                text = ACTOR.format(index=index, x=-6.0 + index, y=2.5 + (index % 2))
                built.world.create(create_request({"sdf": text}))
            yield built
        finally:
            built.close()


def ms_per_step(built: Server, steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        built.sim.step()
    return (time.perf_counter() - start) / steps * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=2000, help="steps per measurement")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    without: list[float] = []
    with_actors: list[float] = []
    with server(0) as bare, server(args.actors) as crowded:
        for built in (bare, crowded):  # past the first steps' one-off costs
            ms_per_step(built, 200)
        for _ in range(args.repeats):
            without.append(ms_per_step(bare, args.steps))
            with_actors.append(ms_per_step(crowded, args.steps))
    base, more = statistics.median(without), statistics.median(with_actors)
    table = [
        "| measurement | figure |",
        "| --- | --- |",
        f"| server step, warehouse and tug (lidars, IMU, odometry, tf, poses, clock) | {base:.3f} ms |",
        f"| the same with {args.actors} walking actors | {more:.3f} ms |",
        f"| with actors ÷ without | {more / base:.2f} |",
        f"| cost of one actor per step | {(more - base) / args.actors * 1e3:.0f} µs |",
    ]
    publish("actors", table)


if __name__ == "__main__":
    main()
