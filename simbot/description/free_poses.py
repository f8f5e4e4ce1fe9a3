"""Free poses on a world's floor, from its description: where a robot may start and end (the
Gymnasium environments), where clutter may stand (simbot.variation).

An obstacle is any collision of the world's models (static, and dynamic ones where they start:
the trolley) that reaches into the height the robot occupies, from just above the floor
(`FLOOR_TOLERANCE`) to the top of its highest collision; its shadow on the floor is the convex
hull of the box holding it (`footprints.py`). The floor is what lies at floor level (a `<plane>`,
or a collision whose top is within `FLOOR_TOLERANCE` of z = 0); the area poses are drawn from is
the floor's extent, clipped to `MAX_HALF_WIDTH` around the origin (the empty world's 100 m plane
would put goals 50 m away), unless the environment is given an `area`.

A pose is free when the robot's shadow, grown by the clearance on every side, overlaps no
obstacle's and lies inside the area. Models added at start (the warehouse's walking people) are
not obstacles here: they move.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from simbot.description.footprints import Floats, Planar, Rectangle, collision_boxes, convex_hull, overlap, reaches_into
from simbot.description.model import Model, Plane, World
from simbot.transform import matmul

log = logging.getLogger(__name__)

FLOOR_TOLERANCE = 0.01
"""Metres: what lies no higher than this above z = 0 is floor, not an obstacle."""
MAX_HALF_WIDTH = 10.0
"""Metres: the default area reaches at most this far from the origin along x and y."""
MAX_TRIES = 2000
"""Draws before a free pose is given up on (the warehouse needs a handful)."""


class NoFreePose(ValueError):
    """A pose asked for is not free, or none could be found: one line naming it and the obstacle."""


Area = tuple[float, float, float, float]
"""(xmin, ymin, xmax, ymax) in the world."""


@dataclass(frozen=True)
class Obstacle:
    """One collision's shadow on the floor, with a circle around it for a quick first test."""

    name: str
    """`model::link::collision`, as the error for a blocked pose names it."""
    polygon: Floats
    centre: tuple[float, float]
    radius: float

    @staticmethod
    def of(name: str, points: Floats) -> Obstacle:
        hull = convex_hull(points)
        centre = hull.mean(axis=0)
        radius = float(np.hypot(*(hull - centre).T).max())
        return Obstacle(name, hull, (float(centre[0]), float(centre[1])), radius)


class Places:
    """Which poses are free for the robot in one world, and seeded draws of them."""

    def __init__(self, obstacles: Sequence[Obstacle], area: Area, footprint: Rectangle, clearance: float) -> None:
        self.obstacles = list(obstacles)
        self.area = area
        self.footprint = footprint
        self.grown = footprint.grown(clearance)
        self.clearance = clearance

    @staticmethod
    def of_world(world: World, footprint: Rectangle, robot_top: float, clearance: float, area: Area | None) -> Places:
        """The obstacles and the floor of `world` for a robot of `footprint`, `robot_top` high."""
        obstacles: list[Obstacle] = []
        floor: list[Area] = []
        for model in world.models:
            _shadows(model, robot_top, obstacles, floor)
        if area is None:
            area = _default_area(floor)
        xmin, ymin, xmax, ymax = area
        if not (xmin < xmax and ymin < ymax):
            raise NoFreePose(f"area {area}: needs xmin < xmax and ymin < ymax")
        log.debug("%s: %d obstacles, area %s", world.name, len(obstacles), area)
        return Places(obstacles, area, footprint, clearance)

    def blocker(self, pose: Planar) -> str | None:
        """Why the robot cannot stand at `pose`: the obstacle it would touch (with the clearance), or
        that it would leave the area; None when it is free."""
        corners = self.grown.placed(pose)
        xmin, ymin, xmax, ymax = self.area
        body = self.footprint.placed(pose)
        if body[:, 0].min() < xmin or body[:, 0].max() > xmax or body[:, 1].min() < ymin or body[:, 1].max() > ymax:
            return f"outside the area {self.area}"
        reach = self.grown.radius
        for obstacle in self.obstacles:
            if math.hypot(obstacle.centre[0] - pose[0], obstacle.centre[1] - pose[1]) > obstacle.radius + reach:
                continue
            if overlap(corners, obstacle.polygon):
                return f"within {self.clearance:g} m of {obstacle.name}"
        return None

    def check(self, pose: Planar, what: str) -> None:
        """NoFreePose naming `what` (\"goal\") and the obstacle when `pose` is not free."""
        why = self.blocker(pose)
        if why is not None:
            x, y, yaw = pose
            raise NoFreePose(f"{what} ({x:g}, {y:g}, {yaw:g}) is not free for the robot: {why}")

    def draw(self, rng: np.random.Generator, what: str) -> Planar:
        """A free pose anywhere in the area, uniformly, with a uniform heading."""
        xmin, ymin, xmax, ymax = self.area
        for _ in range(MAX_TRIES):
            pose = (
                float(rng.uniform(xmin, xmax)),
                float(rng.uniform(ymin, ymax)),
                float(rng.uniform(-math.pi, math.pi)),
            )
            if self.blocker(pose) is None:
                return pose
        raise NoFreePose(f"no free {what} found in {MAX_TRIES} draws in the area {self.area}")

    def draw_near(self, rng: np.random.Generator, centre: Planar, distance: tuple[float, float], what: str) -> Planar:
        """A free pose `distance` (min, max) metres from `centre`, in a uniform direction, with a uniform heading."""
        low, high = distance
        for _ in range(MAX_TRIES):
            r, bearing = float(rng.uniform(low, high)), float(rng.uniform(-math.pi, math.pi))
            pose = (
                centre[0] + r * math.cos(bearing),
                centre[1] + r * math.sin(bearing),
                float(rng.uniform(-math.pi, math.pi)),
            )
            if self.blocker(pose) is None:
                return pose
        raise NoFreePose(
            f"no free {what} found {low:g}–{high:g} m from ({centre[0]:g}, {centre[1]:g}) in {MAX_TRIES} draws"
        )


def _shadows(model: Model, robot_top: float, obstacles: list[Obstacle], floor: list[Area]) -> None:
    """Adds the model's obstacles and floor pieces: its planes, and the boxes at floor level, are
    floor; the boxes reaching into the robot's heights are obstacles (not those above it: a
    trolley's deck, a shelf, a sign)."""
    placed = model.pose.matrix()
    for link in model.links:
        for collision in link.collisions:
            if isinstance(collision.geometry, Plane):
                width, depth = collision.geometry.size
                centre = matmul(matmul(placed, link.pose.matrix()), collision.pose.matrix())[:2, 3]
                floor.append(
                    (centre[0] - width / 2, centre[1] - depth / 2, centre[0] + width / 2, centre[1] + depth / 2)
                )
    for link, collision, corners in collision_boxes(model, placed):
        high = float(corners[:, 2].max())
        if high <= FLOOR_TOLERANCE:
            if high >= -FLOOR_TOLERANCE:
                xy = corners[:, :2]
                floor.append((xy[:, 0].min(), xy[:, 1].min(), xy[:, 0].max(), xy[:, 1].max()))
        elif reaches_into(corners, FLOOR_TOLERANCE, robot_top):
            obstacles.append(Obstacle.of(f"{model.name}::{link.name}::{collision.name}", corners[:, :2]))


def _default_area(floor: list[Area]) -> Area:
    if not floor:
        raise NoFreePose("the world has no floor (a <plane>, or a collision whose top is at z = 0): give an area")
    m = MAX_HALF_WIDTH
    return (
        max(-m, float(min(a[0] for a in floor))),
        max(-m, float(min(a[1] for a in floor))),
        min(m, float(max(a[2] for a in floor))),
        min(m, float(max(a[3] for a in floor))),
    )
