"""Collision shapes as the boxes that hold them, and their shadows on the floor: the one source of
them for placing the robot and clutter (`free_poses.py`), the gym's view of the robot's shape
(simbot/gym/robot.py) and the people's obstacles (simbot/sim/systems/crowd.py); and the planar
geometry of those shadows (convex hulls, whether two convex polygons overlap).

A box is safe, not exact: every shape is taken as the box that holds it (a cylinder as its square
prism, a sphere as its cube), so a pose free of the boxes is free in the world too. Shapes without
a size of their own (meshes, heightmaps, polylines) are left out with a debug line: their model is
not an obstacle here. The exact shadow of every shape in a band of heights, for the map, is
simbot.mapping.shapes, whose boxes are these.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.model import Box, Capsule, Collision, Cone, Cylinder, Ellipsoid, Geometry, Link, Model, Sphere
from simbot.description.model_memo import per_model
from simbot.transform import matmul

log = logging.getLogger(__name__)

Floats = npt.NDArray[np.float64]
Planar = tuple[float, float, float]
"""(x, y, yaw) in the world: a pose on the floor."""
BOX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
"""A box's 8 corners about its centre, in half sizes, numbered by their (x, y, z) sides as bits."""


def box_size(geometry: Geometry) -> tuple[float, float, float] | None:
    """The size of the box holding `geometry` in its own frame; None for shapes without a size (meshes)."""
    if isinstance(geometry, Box):
        return geometry.size
    if isinstance(geometry, (Cylinder, Cone)):
        return (2 * geometry.radius, 2 * geometry.radius, geometry.length)
    if isinstance(geometry, Capsule):
        return (2 * geometry.radius, 2 * geometry.radius, geometry.length + 2 * geometry.radius)
    if isinstance(geometry, Sphere):
        return (2 * geometry.radius,) * 3
    if isinstance(geometry, Ellipsoid):
        x, y, z = geometry.radii
        return (2 * x, 2 * y, 2 * z)
    return None


def box_corners(size: tuple[float, float, float], frame: Floats) -> Floats:
    """The 8 corners (8 × 3) of a box of `size` centred in `frame` (4 × 4, the box's frame in its parent)."""
    half = np.asarray(size, dtype=np.float64) / 2
    local = np.hstack([BOX_SIGNS * half, np.ones((8, 1))])
    corners: Floats = matmul(local, frame.T)[:, :3]
    return corners


def collision_corners(collision: Collision, parent: Floats) -> Floats | None:
    """The corners of the box holding `collision`, in the frame `parent` (4 × 4) places its link in;
    None (with a debug line) for a shape without a size."""
    size = box_size(collision.geometry)
    if size is None:
        log.debug("%s: a %s has no size here; not an obstacle", collision.name, type(collision.geometry).__name__)
        return None
    return box_corners(size, matmul(parent, collision.pose.matrix()))


def collision_boxes(model: Model, placed: Floats | None = None) -> list[tuple[Link, Collision, Floats]]:
    """Each collision of `model` that has a size, with the corners of the box holding it: in the
    model's frame, or in the world where `placed` (4 × 4) puts the model there."""
    found = []
    for link in model.links:
        frame = link.pose.matrix() if placed is None else matmul(placed, link.pose.matrix())
        for collision in link.collisions:
            corners = collision_corners(collision, frame)
            if corners is not None:
                found.append((link, collision, corners))
    return found


@per_model
def outline(model: Model) -> Floats:
    """The convex hull on the floor (k × 2, the model's frame) of the boxes holding its collisions:
    the ground it takes up, which no other robot may be created on."""
    corners = [corners[:, :2] for _, _, corners in collision_boxes(model)]
    return convex_hull(np.concatenate(corners)) if corners else np.zeros((0, 2))


def reach(points: Floats) -> float:
    """How far the farthest of `points` (k × 2, a body's frame) lies from the frame's origin: two
    bodies farther apart than their reaches added cannot overlap."""
    return float(np.hypot(points[:, 0], points[:, 1]).max()) if len(points) else 0.0


def in_world(points: Floats, pose: Planar) -> Floats:
    """`points` (k × 2, a body's frame) in the world with the body at `pose` (x, y, yaw)."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.stack([x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]], axis=1)


def reaches_into(corners: Floats, low: float, high: float) -> bool:
    """Whether a box (its corners) reaches into the heights between `low` and `high`; a box that only
    touches one of them does not."""
    return float(corners[:, 2].max()) > low and float(corners[:, 2].min()) < high


def convex_hull(points: Floats) -> Floats:
    """The convex hull of 2-D points (n × 2), counter-clockwise, without repeated points (Andrew's monotone chain)."""
    unique = sorted({(float(x), float(y)) for x, y in points})
    if len(unique) <= 2:
        return np.array(unique, dtype=np.float64)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    upper: list[tuple[float, float]] = []
    for chain, ordered in ((lower, unique), (upper, unique[::-1])):
        for point in ordered:
            while len(chain) >= 2 and cross(chain[-2], chain[-1], point) <= 0:
                chain.pop()
            chain.append(point)
    return np.array(lower[:-1] + upper[:-1], dtype=np.float64)


def _axes(polygon: Floats) -> Floats:
    """The outward normals of a polygon's edges (not normalised): the separating axes it offers."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    return np.stack([edges[:, 1], -edges[:, 0]], axis=1)


def overlap(a: Floats, b: Floats) -> bool:
    """Whether two convex polygons (k × 2) overlap (touching counts): no separating axis among their
    edges' normals. Products written out term by term, as simbot.transform's are, so that a
    placement is the same on every CPU."""
    if len(a) == 0 or len(b) == 0:
        return False
    for axes in (_axes(a), _axes(b)):
        for axis in axes:
            pa, pb = a[:, 0] * axis[0] + a[:, 1] * axis[1], b[:, 0] * axis[0] + b[:, 1] * axis[1]
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


@dataclass(frozen=True)
class Rectangle:
    """An axis-aligned rectangle in a body's own frame: the robot's shadow on the floor."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float

    def grown(self, margin: float) -> Rectangle:
        return Rectangle(self.xmin - margin, self.xmax + margin, self.ymin - margin, self.ymax + margin)

    def corners(self) -> Floats:
        return np.array(
            [[self.xmin, self.ymin], [self.xmax, self.ymin], [self.xmax, self.ymax], [self.xmin, self.ymax]],
            dtype=np.float64,
        )

    def placed(self, pose: Planar) -> Floats:
        """The corners (4 × 2, counter-clockwise) in the world with the body at `pose`."""
        return in_world(self.corners(), pose)

    @property
    def radius(self) -> float:
        """The distance from the frame's origin to the farthest corner."""
        return float(max(math.hypot(x, y) for x, y in self.corners()))


def wrap(angle: float) -> float:
    """`angle` in (−π, π]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def relative(target: Planar, base: Planar) -> Planar:
    """`target` in the frame of `base`: (x ahead, y to the left, yaw difference)."""
    dx, dy = target[0] - base[0], target[1] - base[1]
    c, s = math.cos(base[2]), math.sin(base[2])
    return (c * dx + s * dy, -s * dx + c * dy, wrap(target[2] - base[2]))
