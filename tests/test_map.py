"""The ground-truth map (simbot.mapping, `simbot map`) against geometry, and read as Nav2 reads it.

Per shape: a world written here holds a box turned 30°, an upright and a tilted cylinder, a sphere
cut off its equator, a concave closed mesh (an L-shaped prism, an OBJ written here) and a
heightmap ramp (a PNG written here). For each, every cell is checked against the shape's own
inside test at the cut height, sampled on the cell: a cell whose samples are all inside is
occupied, a cell (grown by a tenth of a cell) with no sample inside is free, and the occupied
area lies between the cross-section's area and that area grown by one cell's ring
(perimeter × cell diagonal + π · diagonal²), the most a boundary can add.

`simbot map` runs as a real process: its map.pgm and map.yaml are read with PIL and PyYAML, as an
outside reader of Nav2's format would, and the warehouse's north wall (its pose from
worlds/warehouse.sdf through the description reader) is black where the origin and resolution put it.
"""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
import yaml
from conftest import REPO
from PIL import Image

from simbot import cli
from simbot.description import load_world
from simbot.description.model import Box, Collision, Geometry, Link, Model, Sphere
from simbot.description.poses import Pose, rpy_to_matrix
from simbot.mapping.nav2_map import FREE_PIXEL, OCCUPIED_PIXEL
from simbot.mapping.occupancy import LIDAR_HEIGHT, OccupancyGrid, occupancy_grid, static_models, world_map
from simbot.mapping.shapes import Band

Z = LIDAR_HEIGHT
RES = 0.05
SAMPLES = 9
"""Samples per cell side for the inside tests."""
Inside = Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]], npt.NDArray[np.bool_]]

BOX_AT, BOX_SIZE, BOX_YAW = (-3.0, 0.0, 0.5), (2.0, 1.0, 1.0), math.radians(30)
CYL_AT, CYL_R, CYL_L = (0.0, 3.0, 0.5), 0.5, 1.0
TILT_AT, TILT_R, TILT_L, TILT = (3.0, 3.0, Z), 0.2, 2.0, math.radians(45)
SPHERE_AT, SPHERE_R = (3.0, 0.0, 0.5), 0.6
L_AT = (0.0, -3.0, 0.0)
L_OUTLINE = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.4), (0.4, 0.4), (0.4, 1.0), (0.0, 1.0)]
RAMP_AT, RAMP_SIZE, RAMP_RISE = (-4.0, -4.0, 0.0), 4.0, 1.0


def _model(name: str, pose: tuple[float, ...], geometry: str) -> str:
    return (
        f"<model name='{name}'><static>true</static><pose>{' '.join(map(str, pose))}</pose>"
        f"<link name='link'><collision name='c'><geometry>{geometry}</geometry></collision></link></model>"
    )


def _l_prism_obj() -> str:
    """The L outline extruded from z = 0 to 1, closed: fan caps from its corner (0, 0), which sees every vertex."""
    n = len(L_OUTLINE)
    lines = [f"v {x} {y} 0" for x, y in L_OUTLINE] + [f"v {x} {y} 1" for x, y in L_OUTLINE]
    caps = [(0, k + 1, k) for k in range(1, n - 1)] + [(n, n + k, n + k + 1) for k in range(1, n - 1)]
    sides = [t for k in range(n) for t in ((k, (k + 1) % n, n + (k + 1) % n), (k, n + (k + 1) % n, n + k))]
    return "\n".join(lines + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in caps + sides]) + "\n"


@pytest.fixture(scope="module")
def shapes_world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("shapes")
    (folder / "l.obj").write_text(_l_prism_obj())
    ramp = np.tile(np.round(np.linspace(0, 65535, 65)).astype(np.uint16), (65, 1))  # 16 bits: rises along +x
    cv2.imwrite(str(folder / "ramp.png"), ramp)
    models = [
        _model("box", (*BOX_AT, 0, 0, BOX_YAW), "<box><size>{} {} {}</size></box>".format(*BOX_SIZE)),
        _model(
            "cylinder", (*CYL_AT, 0, 0, 0), f"<cylinder><radius>{CYL_R}</radius><length>{CYL_L}</length></cylinder>"
        ),
        _model(
            "tilted", (*TILT_AT, 0, TILT, 0), f"<cylinder><radius>{TILT_R}</radius><length>{TILT_L}</length></cylinder>"
        ),
        _model("sphere", (*SPHERE_AT, 0, 0, 0), f"<sphere><radius>{SPHERE_R}</radius></sphere>"),
        _model("mesh", (*L_AT, 0, 0, 0), "<mesh><uri>l.obj</uri></mesh>"),
        _model(
            "ramp",
            (*RAMP_AT, 0, 0, 0),
            f"<heightmap><uri>ramp.png</uri><size>{RAMP_SIZE} {RAMP_SIZE} {RAMP_RISE}</size></heightmap>",
        ),
        _model("ground", (0, 0, 0, 0, 0, 0), "<plane><normal>0 0 1</normal><size>30 30</size></plane>"),
    ]
    path = folder / "shapes.sdf"
    path.write_text(f"<?xml version='1.0'?><sdf version='1.9'><world name='shapes'>{''.join(models)}</world></sdf>")
    return path


@pytest.fixture(scope="module")
def grid(shapes_world: Path) -> OccupancyGrid:
    return world_map(load_world(shapes_world))


def _box(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    c, s = math.cos(BOX_YAW), math.sin(BOX_YAW)
    u, v = (x - BOX_AT[0]) * c + (y - BOX_AT[1]) * s, -(x - BOX_AT[0]) * s + (y - BOX_AT[1]) * c
    return (np.abs(u) < BOX_SIZE[0] / 2) & (np.abs(v) < BOX_SIZE[1] / 2)


def _cylinder(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    return np.hypot(x - CYL_AT[0], y - CYL_AT[1]) < CYL_R


def _tilted(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """Within the radius of the axis (pitched by TILT about y) and between the caps, at height Z."""
    axis = rpy_to_matrix((0.0, TILT, 0.0))[:, 2]
    d = np.stack([x - TILT_AT[0], y - TILT_AT[1], np.full_like(x, Z - TILT_AT[2])], axis=-1)
    along = d[..., 0] * axis[0] + d[..., 1] * axis[1] + d[..., 2] * axis[2]
    across = d - along[..., None] * axis
    return (np.sqrt((across**2).sum(axis=-1)) < TILT_R) & (np.abs(along) < TILT_L / 2)


def _sphere(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    return (x - SPHERE_AT[0]) ** 2 + (y - SPHERE_AT[1]) ** 2 + (Z - SPHERE_AT[2]) ** 2 < SPHERE_R**2


def _l_prism(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    u, v = x - L_AT[0], y - L_AT[1]
    return (u > 0) & (v > 0) & (((u < 1) & (v < 0.4)) | ((u < 0.4) & (v < 1)))


def _ramp(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    u, v = x - RAMP_AT[0], y - RAMP_AT[1]
    height = (u + RAMP_SIZE / 2) / RAMP_SIZE * RAMP_RISE
    return (np.abs(u) < RAMP_SIZE / 2) & (np.abs(v) < RAMP_SIZE / 2) & (height > Z)


SHAPES: dict[str, tuple[Inside, tuple[float, float, float, float], float, float]] = {
    # name: inside test, the window it lies in (xmin, ymin, xmax, ymax), cross-section area and perimeter
    "box": (_box, (-4.5, -1.5, -1.5, 1.5), 2.0, 6.0),
    "upright cylinder": (_cylinder, (-1.0, 2.0, 1.0, 4.0), math.pi * CYL_R**2, 2 * math.pi * CYL_R),
    "tilted cylinder": (
        _tilted,
        (2.5, 2.5, 3.5, 3.5),
        math.pi * TILT_R * TILT_R / math.cos(TILT),
        2 * math.pi * TILT_R / math.cos(TILT),  # more than the ellipse's perimeter
    ),
    "sphere": (
        _sphere,
        (2.0, -1.0, 4.0, 1.0),
        math.pi * (SPHERE_R**2 - (SPHERE_AT[2] - Z) ** 2),
        2 * math.pi * math.sqrt(SPHERE_R**2 - (SPHERE_AT[2] - Z) ** 2),
    ),
    "closed concave mesh": (_l_prism, (-0.5, -3.5, 1.5, -1.5), 0.64, 4.0),
    "heightmap": (_ramp, (-6.5, -6.5, -1.5, -1.5), (RAMP_SIZE - Z / RAMP_RISE * RAMP_SIZE) * RAMP_SIZE, 4 * RAMP_SIZE),
}


def _samples(grid: OccupancyGrid, rows: npt.NDArray[np.int64], cols: npt.NDArray[np.int64], grow: float) -> tuple:
    """SAMPLES² points over each cell (rows × cols), the cell grown by `grow` cells at each side."""
    t = np.linspace(-grow, 1 + grow, SAMPLES)
    ox, oy = grid.origin
    x = ox + (cols[..., None, None] + t[None, :]) * grid.resolution
    y = oy + (rows[..., None, None] + t[:, None]) * grid.resolution
    return np.broadcast_arrays(x, y)


@pytest.mark.parametrize("shape", list(SHAPES))
def test_each_shape_fills_the_cells_its_cross_section_overlaps(grid: OccupancyGrid, shape: str) -> None:
    inside, (xmin, ymin, xmax, ymax), area, perimeter = SHAPES[shape]
    (r0, c0), (r1, c1) = grid.cell_of(xmin, ymin), grid.cell_of(xmax, ymax)
    r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1, grid.occupied.shape[0]), min(c1, grid.occupied.shape[1])
    rows, cols = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    occupied = grid.occupied[r0:r1, c0:c1]
    whole = inside(*_samples(grid, rows, cols, 0.0)).all(axis=(-1, -2))
    clear = ~inside(*_samples(grid, rows, cols, 0.1)).any(axis=(-1, -2))
    assert whole.sum() > 20, "the window holds the shape"
    assert occupied[whole].all(), f"{shape}: {int((~occupied[whole]).sum())} cells inside it are free"
    assert not occupied[clear].any(), f"{shape}: {int(occupied[clear].sum())} cells clear of it are occupied"
    ring = perimeter * RES * math.sqrt(2) + 2 * math.pi * RES * RES
    assert area <= occupied.sum() * RES * RES <= area + ring


def _lone(geometry: Geometry, pose: Pose) -> tuple[Model, Pose]:
    """A static model of one collision, at `pose`."""
    return Model("lone", static=True, links=(Link("link", collisions=(Collision("c", geometry),)),)), pose


def test_a_band_takes_the_widest_cut_of_a_sphere() -> None:
    """Cut above its centre, a sphere leaves the circle at the band's low end; a band holding its
    centre leaves the equator; a band clear of it, nothing."""
    ball = _lone(Sphere(0.6), Pose((0.0, 0.0, 0.5)))
    for band, radius in ((Band(0.9, 1.2), math.sqrt(0.36 - 0.16)), (Band(0.0, 2.0), 0.6), (Band(1.2, 2.0), 0.0)):
        cells = occupancy_grid([ball], band, RES).occupied.sum()
        area = math.pi * radius * radius
        assert area <= cells * RES * RES <= area + 2 * math.pi * radius * RES * math.sqrt(2) + 2 * math.pi * RES * RES


def test_a_band_from_the_floor_leaves_the_floor_out(shapes_world: Path) -> None:
    """The ground plane and a slab whose top is the band's low end only touch the band: open floor stays free."""
    slab = _lone(Box((30.0, 30.0, 0.1)), Pose((0.0, 0.0, -0.05)))
    grid = occupancy_grid([*static_models(load_world(shapes_world)), slab], Band(0.0, 0.3), RES)
    assert not grid.occupied[grid.cell_of(0.0, 1.5)]
    assert grid.occupied[grid.cell_of(*BOX_AT[:2])]


def _run_map(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "simbot.cli", "map", *args], capture_output=True, text=True, timeout=120, cwd=cwd
    )


def test_simbot_map_places_the_warehouse_wall_where_the_world_has_it(tmp_path: Path) -> None:
    done = _run_map("--world", "warehouse", "-o", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    meta = yaml.safe_load((tmp_path / "out" / "map.yaml").read_text())
    assert meta["mode"] == "trinary" and meta["negate"] == 0
    assert (meta["occupied_thresh"], meta["free_thresh"]) == (0.65, 0.25)
    image = Image.open(tmp_path / "out" / meta["image"])
    assert image.format == "PPM" and image.mode == "L"
    pixels = np.asarray(image)
    assert set(np.unique(pixels)) == {OCCUPIED_PIXEL, FREE_PIXEL}
    resolution, (ox, oy, yaw) = meta["resolution"], meta["origin"]
    assert resolution == RES and yaw == 0.0

    walls = load_world(REPO / "worlds" / "warehouse.sdf").model("walls")
    north = next(c for c in walls.links[0].collisions if c.name == "wall_north_collision")
    assert isinstance(north.geometry, Box)
    (wx, wy, _), (sx, sy, _) = north.pose.xyz, north.geometry.size
    height = pixels.shape[0]

    def pixel(x: float, y: float) -> int:
        """The pixel of world (x, y) as map_server places it: the image's top row is the highest y."""
        return int(pixels[height - 1 - math.floor((y - oy) / resolution), math.floor((x - ox) / resolution)])

    for x in np.linspace(wx - sx / 2 + 0.5, wx + sx / 2 - 0.5, 25):
        assert pixel(x, wy) == OCCUPIED_PIXEL, f"the north wall is not at ({x:.2f}, {wy})"
        assert pixel(x, wy - sy / 2 + 0.02) == OCCUPIED_PIXEL
        assert pixel(x, wy - sy / 2 - 0.02) == FREE_PIXEL, "the wall's inner face is where the world has it"
    wall_rows = [r for r in range(height) if pixels[r, pixels.shape[1] // 2] == OCCUPIED_PIXEL and r < height // 4]
    assert len(wall_rows) == round(sy / resolution), "the wall is as thick on the map as in the world"


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--resolution", "0"], "--resolution"),
        (["--resolution", "-0.1"], "--resolution"),
        (["--band", "3:1"], "--band"),
        (["--band", "a:b"], "--band"),
        (["--band", "0.5"], "--band"),
        (["--height", "high"], "--height"),
        (["--world", "no/such/world.sdf"], "no/such/world.sdf"),
        (["--add", "no/such/people.sdf"], "no/such/people.sdf"),
    ],
)
def test_bad_input_is_one_line_naming_it_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], names: str
) -> None:
    """Through `simbot`'s own entry point, in this process (the wall test runs the real one)."""
    assert cli.main(["map", *args, "-o", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and names in lines[0], lines
    assert not (tmp_path / "out").exists()
