"""An occupancy grid as Nav2's map_server reads it: `map.pgm` and `map.yaml`.

The image is a binary PGM (P5), 8 bits, one pixel per cell: occupied 0, free 254 (unknown would
be 205; a map made from the geometry knows every cell). Its top row is the grid's highest y, as
map_server loads it (nav2_map_server's map_io flips the rows back into nav_msgs/OccupancyGrid's
order, row 0 at the origin). The YAML says how to read it:

| key | value |
| --- | --- |
| `image` | the PGM's file name, beside the YAML |
| `mode` | `trinary`: occupied, free or unknown by the thresholds |
| `resolution` | metres per cell |
| `origin` | [x, y, yaw]: the world pose of the lower-left corner of the lower-left cell; yaw 0 |
| `negate` | 0: black is occupied |
| `occupied_thresh`, `free_thresh` | 0.65, 0.25: 0 reads occupied, 254 free, 205 unknown |

The map's frame `map` is the world's (REP-105), so `origin` is in world coordinates.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from simbot.mapping.occupancy import OccupancyGrid

OCCUPIED_PIXEL = 0
FREE_PIXEL = 254
UNKNOWN_PIXEL = 205
OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.25
IMAGE = "map.pgm"
YAML = "map.yaml"


def pgm_bytes(grid: OccupancyGrid) -> bytes:
    """The grid as a binary PGM, its top row the highest y."""
    pixels = np.where(np.flipud(grid.occupied), OCCUPIED_PIXEL, FREE_PIXEL).astype(np.uint8)
    height, width = pixels.shape
    return f"P5\n{width} {height}\n255\n".encode() + pixels.tobytes()


def yaml_text(grid: OccupancyGrid, image: str = IMAGE) -> str:
    """map_server's YAML for the grid's image `image` (numbers written with their shortest exact form)."""
    x, y = grid.origin
    return (
        f"image: {image}\n"
        "mode: trinary\n"
        f"resolution: {grid.resolution!r}\n"
        f"origin: [{x!r}, {y!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {OCCUPIED_THRESH}\n"
        f"free_thresh: {FREE_THRESH}\n"
    )


def write_map(grid: OccupancyGrid, folder: Path) -> tuple[Path, Path]:
    """Writes `folder`/map.pgm and map.yaml (making the folder); each whole or absent. OSError as raised."""
    folder.mkdir(parents=True, exist_ok=True)
    image, yaml = folder / IMAGE, folder / YAML
    _replace(image, pgm_bytes(grid))
    _replace(yaml, yaml_text(grid).encode())
    return image, yaml


def _replace(path: Path, data: bytes) -> None:
    partial = path.with_name(f".{path.name}.{os.getpid()}.part")
    partial.write_bytes(data)
    os.replace(partial, path)
