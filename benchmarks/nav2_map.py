"""`simbot map`'s map read back as Nav2's map_server reads it, and clearances on it, for the
benchmarks that feed Nav2 simbot's data (bench_localisation)."""

from __future__ import annotations

import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from simbot.mapping.command import main as simbot_map


@dataclass(frozen=True)
class Map:
    cells: npt.NDArray[np.int8]
    """nav_msgs/OccupancyGrid's values, row 0 the lowest y: 100 occupied, 0 free, -1 unknown."""
    resolution: float
    origin: tuple[float, float]


def read_map(folder: Path) -> Map:
    """map.yaml and its image as nav2_map_server's map_io loads them (trinary, negate 0)."""
    entries = dict(line.split(":", 1) for line in (folder / "map.yaml").read_text().splitlines() if ":" in line)
    values = {key.strip(): value.strip() for key, value in entries.items()}
    assert values["mode"] == "trinary" and values["negate"] == "0", values
    image = cv2.imread(str(folder / values["image"]), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SystemExit(f"{folder / values['image']}: not an image")
    occupancy = (255.0 - image.astype(np.float64)) / 255.0
    cells = np.full(image.shape, -1, dtype=np.int8)
    cells[occupancy > float(values["occupied_thresh"])] = 100
    cells[occupancy < float(values["free_thresh"])] = 0
    origin = [float(v) for v in values["origin"].strip("[]").split(",")]
    return Map(np.flipud(cells), float(values["resolution"]), (origin[0], origin[1]))


def simbot_warehouse_map() -> Map:
    with tempfile.TemporaryDirectory() as folder:
        if simbot_map(["--world", "warehouse", "-o", folder]) != 0:
            raise SystemExit("simbot map failed")
        return read_map(Path(folder))


def _clearance(grid: Map) -> npt.NDArray[np.float32]:
    """Metres from each cell's centre to the nearest occupied cell's."""
    free = (grid.cells != 100).astype(np.uint8)
    return cv2.distanceTransform(free, cv2.DIST_L2, 5) * grid.resolution


def closest_approach(grid: Map, poses: Sequence[tuple[float, float, float]], chassis: tuple[float, float]) -> float:
    """m: the least distance from the outline of a `chassis` (length, width) at each of `poses` (x, y,
    yaw) to an occupied cell (cell centres), less half a cell."""
    distance = _clearance(grid)
    length, width = chassis
    u = np.linspace(-0.5, 0.5, 43)
    outline = np.concatenate(
        [
            np.stack([u * length, np.full_like(u, width / 2)], 1),
            np.stack([u * length, np.full_like(u, -width / 2)], 1),
            np.stack([np.full_like(u, length / 2), u * width], 1),
            np.stack([np.full_like(u, -length / 2), u * width], 1),
        ]
    )
    least = math.inf
    for x, y, yaw in poses:
        c, s = math.cos(yaw), math.sin(yaw)
        wx, wy = x + c * outline[:, 0] - s * outline[:, 1], y + s * outline[:, 0] + c * outline[:, 1]
        cols = np.floor((wx - grid.origin[0]) / grid.resolution).astype(int)
        rows = np.floor((wy - grid.origin[1]) / grid.resolution).astype(int)
        least = min(least, float(distance[rows, cols].min()))
    return least - grid.resolution / 2
