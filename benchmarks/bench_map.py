"""Benchmark of the ground-truth map (simbot.mapping): the warehouse's map at 0.05 m, in CPU time,
against loading the warehouse's description in the same run.

Each round loads worlds/warehouse.sdf (the description reader, as `simbot map` and the server
start with), cuts and fills its map at the lidars' height (what `simbot map` does after loading),
and re-fills the map from the pieces already cut (what the server's MapPublisher does when a
static model comes or goes). A figure is the median over `--rounds` rounds of process CPU time.

    python benchmarks/bench_map.py [--rounds R]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tables import publish

from simbot.description import load_world
from simbot.mapping.occupancy import LIDAR_HEIGHT, RESOLUTION, model_pieces, rasterise, static_models, world_map
from simbot.mapping.shapes import Band

WAREHOUSE = Path(__file__).resolve().parents[1] / "worlds" / "warehouse.sdf"


def cpu_seconds(work: Callable[..., Any], *args: Any) -> tuple[float, Any]:
    """Process CPU time of one call, and what it returned."""
    start = time.process_time()
    result = work(*args)
    return time.process_time() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    band = Band.at(LIDAR_HEIGHT)
    loads, maps, refills = [], [], []
    for _ in range(args.rounds):
        load, world = cpu_seconds(load_world, WAREHOUSE)
        made, grid = cpu_seconds(world_map, world)
        pieces = [model_pieces(model, pose, band) for model, pose in static_models(world)]
        refill, _ = cpu_seconds(rasterise, pieces, RESOLUTION)
        loads.append(load)
        maps.append(made)
        refills.append(refill)
    load, made, refill = (statistics.median(figures) for figures in (loads, maps, refills))
    height, width = grid.occupied.shape
    table = [
        f"| measurement (median of {args.rounds} rounds, CPU time) | figure |",
        "| --- | --- |",
        f"| load the warehouse's description | {load * 1e3:.0f} ms |",
        f"| its map at {RESOLUTION} m, {LIDAR_HEIGHT} m up ({width} × {height} cells, {len(pieces)} static models) "
        f"| {made * 1e3:.1f} ms |",
        f"| map ÷ load | {made / load:.3f} |",
        f"| the server's re-fill from cut pieces (a static model came or went) | {refill * 1e3:.1f} ms |",
    ]
    publish("map", table)


if __name__ == "__main__":
    main()
