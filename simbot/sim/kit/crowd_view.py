"""What a world's people see of it, for the crowd (simbot.sim.systems.crowd) to think in one pass:
the bodies sorted by kind once per set of them (people, robots, bodies moved by others, static
ones), each height band's shadows (`Band`), and where the bodies stand at a step, each read from
the physics once however many people ask (`Poses`).

Obstacles are the collisions of static models reaching into a band (a person's height, from its
soles up), each as the rectangle holding its shadow (meshes are not obstacles). Robots are the
moving bodies with plugins of their own (not actors): their shadows move with them, and the one
rectangle holding them is their outline. Bodies that move but have no plugin (a trolley) are
obstacles read where they stand.
"""

from __future__ import annotations

import math

import numpy as np

from simbot.description.actor_scripts import ActorModel
from simbot.description.footprints import collision_boxes, reaches_into
from simbot.description.model import Model
from simbot.sim.kit.social_force import Boxes, Floats
from simbot.sim.physics.protocols import WorldAccess
from simbot.transform import Transform


def shadows(model: Model, low: float, high: float) -> Boxes:
    """The rectangles holding the shadows of the model's collisions that reach from `low` to `high`
    (heights in the model's frame), in the model's frame."""
    rectangles = []
    for _, _, corners in collision_boxes(model):
        if not reaches_into(corners, low, high):
            continue
        along, across = corners[4] - corners[0], corners[2] - corners[0]
        if abs(along[2]) < 1e-9 and abs(across[2]) < 1e-9:  # upright: its own rectangle
            centre = corners.mean(axis=0)
            yaw = math.atan2(along[1], along[0])
            rectangles.append((centre[0], centre[1], yaw, np.hypot(*along[:2]) / 2, np.hypot(*across[:2]) / 2))
        else:  # tilted (a wheel): the axis-aligned box holding it
            (x0, y0), (x1, y1) = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
            rectangles.append(((x0 + x1) / 2, (y0 + y1) / 2, 0.0, (x1 - x0) / 2, (y1 - y0) / 2))
    return Boxes.of(rectangles)


def planar(pose: Transform) -> tuple[float, float, float]:
    """x, y and heading of a pose."""
    return pose.position[0], pose.position[1], pose.yaw


class Poses:
    """Where bodies stand at this step, each read from the physics once however many people ask."""

    def __init__(self, physics: WorldAccess) -> None:
        self._physics = physics
        self._at: dict[str, tuple[float, float, float]] = {}

    def planar(self, name: str) -> tuple[float, float, float]:
        """x, y and heading of the body `name`."""
        if name not in self._at:
            self._at[name] = planar(self._physics.model_pose(name))
        return self._at[name]

    def frames(self, names: list[str]) -> Floats:
        """len(names) × 3: each body's x, y and heading."""
        return np.array([self.planar(name) for name in names], dtype=np.float64).reshape(-1, 3)


class Band:
    """The shadows in one height band (world heights `low` to `high`): static obstacles where they
    stand, and the robots' and the movable bodies' in their own frames."""

    def __init__(self, physics: WorldAccess, names: tuple[str, ...], low: float, high: float) -> None:
        moving = set(physics.moving_bodies())
        self.robots: list[str] = []
        self._footprints: dict[str, Boxes] = {}
        outlines, static = [], []
        self._movables: dict[str, Boxes] = {}
        for name in names:
            model = physics.model_of(name)
            if isinstance(model, ActorModel):
                continue
            pose = physics.model_pose(name)
            boxes = shadows(model, low - pose.position[2], high - pose.position[2])
            if name in moving and model.plugins and len(boxes):  # moves by itself, at the band's height
                self.robots.append(name)
                self._footprints[name] = boxes
                outlines.append(boxes.outline())
            elif name in moving:
                self._movables[name] = boxes
            elif len(boxes):
                static.append(boxes.placed(*planar(pose)))
        self._outlines = Boxes.joined(outlines)
        self.obstacles = Boxes.joined(static)

    def outlines_at(self, poses: Poses) -> Boxes:
        """Each robot's outline where it stands now, in the order of `robots`."""
        return self._outlines.posed(poses.frames(self.robots))

    def footprints_at(self, names: list[str], poses: Poses) -> Boxes:
        """The footprints of the robots `names` where they stand now."""
        return Boxes.joined([self._footprints[n].placed(*poses.planar(n)) for n in names])

    def movables_at(self, poses: Poses) -> Boxes:
        """The shadows of the bodies moved by others (a trolley) where they stand now."""
        return Boxes.joined([boxes.placed(*poses.planar(name)) for name, boxes in self._movables.items()])


class View:
    """A world's bodies as its people see them: who the people are, and each height band's shadows,
    sorted again when the set of bodies changes (a model created or removed)."""

    def __init__(self, physics: WorldAccess) -> None:
        self._physics = physics
        self._names: tuple[str, ...] = ()
        self.people: tuple[str, ...] = ()
        """Every actor's body, these people among them."""
        self._bands: dict[tuple[float, float], Band] = {}

    def refresh(self, names: tuple[str, ...]) -> bool:
        """Sorts the bodies `names` (the world's now) again where they are not those of the last
        call: whether they were not."""
        if names == self._names:
            return False
        self._names, self._bands = names, {}
        self.people = tuple(name for name in names if isinstance(self._physics.model_of(name), ActorModel))
        return True

    def band(self, low: float, high: float) -> Band:
        """The shadows between the world heights `low` and `high`."""
        if (low, high) not in self._bands:
            self._bands[low, high] = Band(self._physics, self._names, low, high)
        return self._bands[low, high]
