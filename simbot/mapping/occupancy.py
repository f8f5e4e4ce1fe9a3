"""A world's collision geometry as an occupancy grid: the ground-truth map of what stands in a height band.

    grid = occupancy_grid(static_models(world), Band.at(LIDAR_HEIGHT), 0.05)

`occupancy_grid` takes models with their world poses (`Placed`), so a caller rasterises whatever
set it holds: a world's static models (`static_models`), the people where their scripts put them
at a time (`people_at`), the running world's models (simbot.sim.systems.map_publisher), or a
randomised world's clutter. Every collision of every link counts, placed at the link's pose in its
model (a static model's joints stand at zero). What each shape leaves in the band, and the cell
rule (a cell is occupied iff the shape's part in the band overlaps the cell's open square), are
simbot.mapping.shapes' and simbot.mapping.raster's docstrings.

The grid spans the whole shapes of what it holds (every height, not only the band), snapped out to
multiples of the resolution (the warehouse: its walls' outer faces, ±10 m); planes span it only
where nothing else does (a world of a ground plane alone: the plane's `<size>`). Row 0 is the
lowest y, as nav_msgs/OccupancyGrid's data runs; an image's top row is the other end
(simbot.mapping.nav2_map).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import ActorModel, is_actor
from simbot.description.model import Model, World
from simbot.description.poses import Pose
from simbot.mapping.raster import Layout, fill_discs, fill_polygons, fill_section, ordered, padded
from simbot.mapping.shapes import Band, Pieces, add_collision
from simbot.transform import matmul

log = logging.getLogger(__name__)

LIDAR_HEIGHT = 0.355
"""Metres above the floor of the Flexley Tug's lidar beams, the default height of a map: 0.26 m above
base_footprint (base_scan_front's link at 0.04 m, its sensor 0.22 m above that: urdf/flexley_tug.sdf),
which rests 0.0955 m up on its tyres (tests/test_map_outside.py checks both on a running tug)."""
RESOLUTION = 0.05
"""Metres per cell: Nav2's usual."""
NOTHING = (-0.5, -0.5, 0.5, 0.5)
"""The extent of a map of nothing: one metre square about the origin."""

Placed = tuple[Model, Pose]
"""A model and its model frame's pose in the world."""


@dataclass(frozen=True)
class OccupancyGrid:
    """`occupied[row, column]`, row 0 the lowest y, column 0 the lowest x, placed by `layout`."""

    occupied: npt.NDArray[np.bool_]
    layout: Layout

    @property
    def resolution(self) -> float:
        return self.layout.resolution

    @property
    def origin(self) -> tuple[float, float]:
        """World xy of cell (0, 0)'s lower-left corner (the `map` frame is `world`, REP-105)."""
        return self.layout.origin

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, column) of the cell holding world point (x, y); it may lie off the grid."""
        ox, oy = self.origin
        return int(np.floor((y - oy) / self.resolution)), int(np.floor((x - ox) / self.resolution))


def static_models(world: World) -> list[Placed]:
    """The world's static models at their poses: what a map holds."""
    return [(model, model.pose) for model in world.models if model.static and not is_actor(model)]


def people_at(world: World, time: float = 0.0) -> list[Placed]:
    """The world's actors where their scripts put them at `time` seconds: their collision proxies
    (and any links of their own) as the lidars see them then."""
    return [
        (model, model.pose @ Pose.from_transform(ScriptPath.of(model.script).pose_at(time)))
        for model in world.models
        if isinstance(model, ActorModel)
    ]


def model_pieces(model: Model, pose: Pose, band: Band) -> Pieces:
    """What `model`, its frame at `pose` in the world, leaves in `band`."""
    pieces = Pieces()
    origin = pose.matrix()
    for link in model.links:
        at_link = matmul(origin, link.pose.matrix())
        for collision in link.collisions:
            add_collision(pieces, collision.geometry, matmul(at_link, collision.pose.matrix()), band, model.source)
    return pieces


def occupancy_grid(
    placed: Iterable[Placed], band: Band, resolution: float = RESOLUTION, layout: Layout | None = None
) -> OccupancyGrid:
    """The grid of `placed` models cut by `band`, over `layout` (default: the extent of what it holds)."""
    return rasterise([model_pieces(model, pose, band) for model, pose in placed], resolution, layout)


def world_map(
    world: World, band: Band | None = None, resolution: float = RESOLUTION, people: bool = False
) -> OccupancyGrid:
    """A world's map: its static models (and, with `people`, its actors at time zero), at LIDAR_HEIGHT by default."""
    placed = static_models(world) + (people_at(world) if people else [])
    return occupancy_grid(placed, band or Band.at(LIDAR_HEIGHT), resolution)


def rasterise(pieces: Sequence[Pieces], resolution: float, layout: Layout | None = None) -> OccupancyGrid:
    """The grid of pieces already cut (a caller that keeps each model's pieces re-rasterises only)."""
    if resolution <= 0 or not np.isfinite(resolution):
        raise ValueError(f"a map's resolution must be a positive number of metres, got {resolution}")
    layout = layout or Layout.around(extent(pieces), resolution)
    cells = layout.empty()
    fill_polygons(cells, layout, padded([hull for p in pieces for hull in p.hulls]))
    bits = [b for p in pieces for b in p.bits]
    if bits:
        fill_polygons(cells, layout, ordered(np.concatenate([_widened(b) for b in bits])))
    discs = [d for p in pieces for d in p.discs]
    fill_discs(cells, layout, np.asarray(discs, dtype=np.float64).reshape(-1, 3))
    for section in (s for p in pieces for s in p.sections):
        if not fill_section(cells, layout, section):
            log.debug("map: a mesh's cross-section does not close; its surface alone is in the map")
    return OccupancyGrid(cells, layout)


def _widened(bits: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Pieces of triangles as 9 points each (a heightmap's have 6: one plane cut them)."""
    return np.concatenate([bits, np.full((len(bits), 9 - bits.shape[1], 2), np.nan)], axis=1)


def extent(pieces: Sequence[Pieces]) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of the whole shapes; of the planes where there is nothing else."""
    points = [b for p in pieces for b in p.bounds] or [b for p in pieces for b in p.floor_bounds]
    if not points:
        return NOTHING
    every = np.concatenate(points)
    (xmin, ymin), (xmax, ymax) = every.min(axis=0), every.max(axis=0)
    return float(xmin), float(ymin), float(xmax), float(ymax)
