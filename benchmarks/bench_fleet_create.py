"""Benchmark of a tug created among a fleet: the wall time from world control's create to the new
tug's first scan and first odometry, against one step of the same fleet, in the same run.

A world built in this process as `simbot-server --robots N --columns 20 --physics kinematic`
builds it (the empty world, the full Flexley Tug: six cameras declared, two lidars, the IMU), in
lockstep, its keys on a `LocalNode`: what the loop itself costs, without Zenoh's declarations of
the new tug's keys or the encoding of the scene it changes (a latched MarkerArray of every visual,
encoded on its own thread in real time: see docs/fleets.md). The fleet steps a while; then the
median wall time of a step is the baseline. Then `--creates` tugs are created one after another,
each clear of the fleet, and stepped until its front scan and its odometry have come: the wall
time from the create to each, and the ratio to the baseline step. N = `--fleets` (100, 300, 1000).

    python benchmarks/bench_fleet_create.py [--fleets 100,300,1000] [--creates 3]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tables import publish

from simbot.bus.local import LocalNode
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.world_control import CreateRequest
from simbot.sim.server import build_world, parse_config

WARM_UP_STEPS = 20
TIMED_STEPS = 20
WAIT_STEPS = 200
"""Steps after a create within which its first scan and odometry must have come (1 s of sim time)."""


def tug_sdf() -> str:
    """The Flexley Tug's SDF with its meshes' paths absolute, as a create request carries it."""
    path = asset("urdf/flexley_tug.sdf")
    return path.read_text(encoding="utf-8").replace("../meshes/", f"{Path(path).parent.parent / 'meshes'}/")


def arrival(came: dict[str, float], leaf: str) -> Callable[[Any], None]:
    """A listener that notes when `leaf`'s first message came."""

    def listen(_msg: Any) -> None:
        came.setdefault(leaf, time.perf_counter())

    return listen


def measure(fleet: int, creates: int) -> tuple[float, list[float], list[float]]:
    """(median wall seconds of a step; each create's seconds to its first scan; to its first odometry)."""
    args = ["--world", "empty", "--robots", str(fleet), "--columns", "20", "--physics", "kinematic"]
    node = LocalNode()
    world = build_world(parse_config([*args, "--mode", "lockstep"]), SimBus(node))
    try:
        for _ in range(WARM_UP_STEPS):
            world.sim.step()
        steps = []
        for _ in range(TIMED_STEPS):
            start = time.perf_counter()
            world.sim.step()
            steps.append(time.perf_counter() - start)
        scans, odometry, sdf = [], [], tug_sdf()
        for k in range(creates):
            name = f"created_{k}"
            came: dict[str, float] = {}
            for leaf in ("lidar_front", "odom"):
                node.hub.listen(f"{name}/{leaf}", arrival(came, leaf))
            start = time.perf_counter()
            world.create(CreateRequest(None, sdf, name, name, Pose(xyz=(-20.0 - 5 * k, -20.0, 0.1)), False))
            for _ in range(WAIT_STEPS):
                world.sim.step()
                if len(came) == 2:
                    break
            if len(came) < 2:
                raise SystemExit(
                    f"{name}: no {' or '.join(set(('lidar_front', 'odom')) - set(came))} in {WAIT_STEPS} steps"
                )
            scans.append(came["lidar_front"] - start)
            odometry.append(came["odom"] - start)
        return statistics.median(steps), scans, odometry
    finally:
        world.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleets", default="100,300,1000", help="fleet sizes, comma-separated")
    parser.add_argument("--creates", type=int, default=3)
    args = parser.parse_args()
    table = [
        "| tugs | a step (median) | create → first scan | create → first odometry | first scan ÷ a step |",
        "| --- | --- | --- | --- | --- |",
    ]
    for fleet in (int(n) for n in args.fleets.split(",")):
        step, scans, odometry = measure(fleet, args.creates)
        scan, odom = statistics.median(scans), statistics.median(odometry)
        table.append(
            f"| {fleet} | {step * 1e3:.1f} ms | {scan:.3f} s ({min(scans):.3f}–{max(scans):.3f}) "
            f"| {odom:.3f} s ({min(odometry):.3f}–{max(odometry):.3f}) | {scan / step:.1f} |"
        )
    publish("fleet_create", table)


if __name__ == "__main__":
    main()
