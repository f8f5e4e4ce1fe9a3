"""The labelled room (tests/fixtures/labelled/room.sdf) and Gazebo's example worlds, shared by the
segmentation and bounding-box camera tests.

Every camera of the room sits at (0, 0, 1) looking along +x: 160 × 120 pixels, 1.2 rad across, so
fx = fy = 80 / tan(0.6) = 116.9 px with the principal point at the image centre (79.5, 59.5). A
world point (x, y, z) lies at u = cx − fx·y/x, v = cy − fx·(z − 1)/x.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from server_helpers import SimServer, drawn_by, running_server

REPO = Path(__file__).resolve().parents[1]
ROOM = str(REPO / "tests" / "fixtures" / "labelled" / "room.sdf")
W, H, HFOV = 160, 120, 1.2
FX = (W / 2) / math.tan(HFOV / 2)
CX, CY = (W - 1) / 2, (H - 1) / 2
EYE_Z = 1.0
CRATES = {"crate_left": (5.0, 1.2), "crate_right": (5.0, -1.2)}
"""The two crates of label 10: 1 m cubes centred at (x, y, 1)."""


def pixel(x: float, y: float, z: float = EYE_Z) -> tuple[float, float]:
    """(u, v) of a world point, by the pinhole model."""
    return CX - FX * y / x, CY - FX * (z - EYE_Z) / x


def box_corners(centre: tuple[float, float, float], size: tuple[float, float, float]) -> list[tuple[float, float]]:
    """The pixels of an axis-aligned box's eight corners."""
    return [
        pixel(centre[0] + sx * size[0] / 2, centre[1] + sy * size[1] / 2, centre[2] + sz * size[2] / 2)
        for sx in (-1, 1)
        for sy in (-1, 1)
        for sz in (-1, 1)
    ]


def room(renderer: str) -> Iterator[SimServer]:
    """The room's server in lockstep (no robot), drawn by `renderer`."""
    with drawn_by(renderer, ROOM, ["--robot", "none"], world_name="labelled_room") as sim:
        yield sim


def runs_without(world: Path, keys: Mapping[str, str]) -> tuple[list[str], dict[str, Any]]:
    """A variant of the room with a bad parameter: the errors its server logs, and a message of each
    of `keys` (the rest of the world runs)."""
    with running_server(str(world), "lockstep", world_name="labelled_room", extra=["--robot", "none"]) as sim:
        got = sim.latest(keys, chunk=34)
        errors = sim.errors()
    return errors, got
