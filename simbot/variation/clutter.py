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
from dataclasses import replace
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
    found = Places.of_world(world, Rectangle(0, 0, 0, 0), TOP, 0.0, clutter.area).obstacles
    for i, (xmin, ymin, xmax, ymax) in enumerate(clutter.keep_clear):
        corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=np.float64)
        found.append(Obstacle.of(f"keep_clear[{i}]", corners))
    for model in world.models:
        if isinstance(model, ActorModel):
            found += _routes(model)
    return found


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
