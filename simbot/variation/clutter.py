"""Clutter on free floor: cartons, pallets and bins where nothing stands, no aisle blocked.

A clutter model stands upright at a drawn (x, y, yaw) inside the profile's area, its shadow on the
floor (the box holding its collisions, `footprints.py`) grown by the clearance clear of: every
model's shadow as the world starts (the trolley where the profile moved it), the rectangles the
profile keeps clear (the aisles, the robot's spawn), each person's route (every leg of its script
as a corridor `ROUTE_HALF_WIDTH` either side), and the clutter placed before it. Each one is static
(an obstacle a map shows) and carries its label (Gazebo's Label system) for segmentation and
bounding-box cameras. A model that finds no free place within `MAX_TRIES` draws is left out, with a
warning: fewer pieces, the same for the same seed.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from simbot.description import load_description
from simbot.description.actor_scripts import ActorModel
from simbot.description.errors import DescriptionError
from simbot.description.footprints import Rectangle, collision_corners
from simbot.description.free_poses import NoFreePose, Obstacle, Places
from simbot.description.model import Model, Param, Plugin, World
from simbot.description.poses import Pose
from simbot.transform import matmul
from simbot.variation.profile import Clutter, ProfileError

log = logging.getLogger(__name__)

ROUTE_HALF_WIDTH = 0.6
"""Metres either side of a person's route kept clear: a shoulder (0.25 m) and a step aside."""
TOP = 3.0
"""Metres: whatever reaches below this (a trolley's deck, a rack's lowest shelf) is in the way."""
PIECE = 1.0
"""Metres: the longest piece a long obstacle is tested as (`_split`)."""
LABEL = Plugin("gz::sim::systems::Label", "gz-sim-label-system")
PREFIX = "clutter_"
"""A clutter model's name: `clutter_<n>`, n from 0 in the order placed."""


def place_clutter(world: World, clutter: Clutter, rng: np.random.Generator) -> tuple[Model, ...]:
    """The clutter models `rng` draws for `world`, placed."""
    count = int(rng.integers(clutter.count[0], clutter.count[1] + 1))
    obstacles = _obstacles(world, clutter)
    placed: list[Model] = []
    for index in range(count):
        piece = clutter.models[int(rng.integers(len(clutter.models)))]
        model = _loaded(piece.file)
        footprint = _footprint(model)
        places = Places(obstacles, clutter.area, footprint, clutter.clearance)
        try:
            x, y, yaw = places.draw(rng, f"place for {model.name}")
        except NoFreePose as exc:
            log.warning("clutter: %s; left out", exc)
            continue
        name = f"{PREFIX}{index}"
        placed.append(_labelled(model, name, Pose((x, y, 0.0), (0.0, 0.0, yaw)), piece.label))
        obstacles.append(Obstacle.of(name, footprint.placed((x, y, yaw))))
    return tuple(placed)


def _obstacles(world: World, clutter: Clutter) -> list[Obstacle]:
    found = [obstacle for model in world.models for obstacle in _shadows(_Shaped.of(world, model), clutter.area)]
    found += _kept_clear(clutter.keep_clear)
    for model in world.models:
        if isinstance(model, ActorModel):
            found += [piece for route in _routes(model) for piece in _split(route)]
    return found


@functools.lru_cache(maxsize=64)
def _kept_clear(rectangles: tuple[tuple[float, float, float, float], ...]) -> list[Obstacle]:
    """The profile's `keep_clear` rectangles as obstacles (in pieces: `_split`)."""
    found = []
    for i, (xmin, ymin, xmax, ymax) in enumerate(rectangles):
        corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=np.float64)
        found += _split(Obstacle.of(f"keep_clear[{i}]", corners))
    return found


def _split(obstacle: Obstacle) -> list[Obstacle]:
    """A long rectangle (an aisle kept clear, a person's route, a wall) as pieces `PIECE` long at
    most, of its name: the same floor covered (a place touches the rectangle where it touches a
    piece), while the quick circle test around each piece spares most of the exact tests."""
    polygon = obstacle.polygon
    if len(polygon) != 4 or obstacle.radius <= PIECE:
        return [obstacle]
    if np.hypot(*(polygon[1] - polygon[0])) < np.hypot(*(polygon[2] - polygon[1])):
        polygon = np.roll(polygon, -1, axis=0)  # the long edges first and third
    a, b, c, d = polygon
    count = int(np.ceil(np.hypot(*(b - a)) / PIECE))
    cuts = [(a + (b - a) * (i / count), d + (c - d) * (i / count)) for i in range(count + 1)]
    return [
        Obstacle.of(obstacle.name, np.array([near, cuts[i + 1][0], cuts[i + 1][1], far]))
        for i, (near, far) in enumerate(cuts[:-1])
    ]


@dataclass(frozen=True)
class _Shaped:
    """A model in its world, known by what its shadows are made of: its pose and its links' collisions."""

    key: tuple[object, ...]
    alone: World = field(compare=False)
    """Its world with it alone."""

    @staticmethod
    def of(world: World, model: Model) -> _Shaped:
        key = (model.name, model.pose, tuple((link.name, link.pose, link.collisions) for link in model.links))
        return _Shaped(key, replace(world, models=(model,)))


@functools.lru_cache(maxsize=1024)
def _shadows(shaped: _Shaped, area: tuple[float, float, float, float]) -> list[Obstacle]:
    """The model's obstacles as the world starts (`Places.of_world`), those that cannot decide a draw
    left out (`_pruned`), long ones in pieces (`_split`); worked out once for each pose and
    collisions of it: a variant that only restyles or keeps a model finds them again."""
    kept = _pruned(Places.of_world(shaped.alone, Rectangle(0, 0, 0, 0), TOP, 0.0, area).obstacles)
    return [piece for obstacle in kept for piece in _split(obstacle)]


def _pruned(obstacles: list[Obstacle]) -> list[Obstacle]:
    """The obstacles without those that cannot decide a draw: one whose shadow lies within another's
    (a rack's shelves within its frame; a pose that touches it touches the other). The same free
    places, fewer tests."""
    kept: list[Obstacle] = []
    for i, obstacle in enumerate(obstacles):
        if not any(j != i and _within(obstacle, other) and (j < i or not _within(other, obstacle))
                   for j, other in enumerate(obstacles)):  # fmt: skip
            kept.append(obstacle)
    return kept


def _within(inner: Obstacle, outer: Obstacle) -> bool:
    """Whether `inner`'s shadow lies in `outer`'s (convex, counter-clockwise), its edges included."""
    if math.hypot(inner.centre[0] - outer.centre[0], inner.centre[1] - outer.centre[1]) > outer.radius:
        return False
    edges = np.roll(outer.polygon, -1, axis=0) - outer.polygon
    for point in inner.polygon:
        offsets = point - outer.polygon
        if (edges[:, 0] * offsets[:, 1] - edges[:, 1] * offsets[:, 0]).min() < 0.0:
            return False
    return True


def _routes(actor: ActorModel) -> list[Obstacle]:
    """Each leg of the actor's script as a corridor on the floor."""
    frame = actor.pose.matrix()
    corridors = []
    for trajectory in actor.script.trajectories:
        points = [matmul(frame, w.pose.matrix())[:2, 3] for w in trajectory.waypoints]
        for i, (a, b) in enumerate(zip(points, points[1:], strict=False)):
            corridors.append(Obstacle.of(f"route of {actor.name} [{i}]", _corridor(a, b)))
    return corridors


def _corridor(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rectangle `ROUTE_HALF_WIDTH` around the segment a–b (a square around a point)."""
    along = b - a
    length = float(np.hypot(*along))
    unit = along / length if length > 1e-9 else np.array([1.0, 0.0])
    side = np.array([-unit[1], unit[0]]) * ROUTE_HALF_WIDTH
    ahead = unit * ROUTE_HALF_WIDTH
    return np.array([a - ahead - side, b + ahead - side, b + ahead + side, a - ahead + side])


@functools.cache
def _loaded(path: Path) -> Model:
    try:
        loaded = load_description(path)
    except DescriptionError as exc:
        raise ProfileError(path, f"clutter model: {exc}") from None
    if not isinstance(loaded, Model):
        raise ProfileError(path, "clutter model: expected a <model>, found a world")
    return loaded


def _footprint(model: Model) -> Rectangle:
    """The rectangle holding the model's collisions' shadows, in its own frame."""
    corners = [
        c
        for link in model.links
        for collision in link.collisions
        if (c := collision_corners(collision, link.pose.matrix())) is not None
    ]
    if not corners:
        raise ProfileError(model.source or Path(model.name), "clutter model: no collision with a size")
    xy = np.vstack(corners)[:, :2]
    return Rectangle(float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max()))


def _labelled(model: Model, name: str, pose: Pose, label: int | None) -> Model:
    plugins = model.plugins if label is None else (*model.plugins, _label(label))
    return replace(model, name=name, pose=pose, static=True, plugins=plugins)


def _label(label: int) -> Plugin:
    return Plugin(LABEL.name, LABEL.filename, (Param("label", str(label)),))
