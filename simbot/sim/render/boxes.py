"""Bounding boxes of labelled objects in a camera's frame, for the bounding-box camera
(simbot/sim/systems/boundingbox_camera.py), as Gazebo's Ogre2BoundingBoxCamera makes them.

An object is one body's visuals of one label (`SceneBody.annotated`; label 0 is background and has
no box), keyed by (instance, label); only objects seen in the frame get a box, as in Gazebo.
- Visible 2D box: the extent of the object's pixels in the `labels` buffer (`label_bits.py`), so what
  hides part of it (labelled or not) shrinks it; corners are pixel indices (ROS's pixel-centre
  coordinates).
- Full 2D box: the object's visual vertices (`visuals.visual_points` of `SceneBody.visuals`),
  posed where the frame's body states put them, projected through the pinhole model
  (u = fx·x/z + cx, v = fx·y/z + cy in the optical frame) and clipped to the image; occlusion does
  not shrink it. Vertices nearer than the near clip are left out.
- 3D box: the axis-aligned box of the object's vertices in its body's root link frame, posed in
  the camera's optical frame (x right, y down, z forward; simbot's camera frame id): centre,
  orientation and size in metres. (Gazebo writes it in Ogre's camera frame, x right, y up, z back.)

Link poses come from the body's URDF joints and the frame's joint positions (revolute and
continuous turn about their axis, prismatic slide along it), so each box shows the frame's instant.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.actor_scripts import SkinnedMesh
from simbot.description.kinematics import KinematicTree, UrdfJoint
from simbot.description.model import Visual
from simbot.sim.render.kinds import Optics
from simbot.sim.render.label_bits import MAX_INSTANCE, labelled
from simbot.sim.render.specs import Frame, SceneBody
from simbot.sim.render.visuals import visual_points
from simbot.transform import Matrix, Transform, matmul, norm, rigid_inverse

Key = tuple[int, int]
"""(instance, label): one object."""
Corners = tuple[float, float, float, float]
"""(u min, v min, u max, v max), pixels."""
OPTICAL_FROM_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
"""A camera's body frame (x forward, z up) to its optical frame (x right, y down, z forward)."""
GREEN = (0, 255, 0)
"""What Gazebo draws the boxes in on the camera's image."""


@dataclass(frozen=True)
class Shape:
    link: str
    label: int
    points: npt.NDArray[np.float64]
    """The visual's vertices in its link's frame."""
    skinned: Visual | None = None
    """A skin's visual, posed at each frame's joint positions (`visuals.visual_points`)."""


@dataclass(frozen=True)
class BodyShapes:
    """A body's labelled visuals, and its joints to pose them."""

    root: str
    joints: tuple[UrdfJoint, ...]
    shapes: tuple[Shape, ...]

    @staticmethod
    def of(body: SceneBody) -> BodyShapes:
        """The labelled visuals' vertices; the joints of the URDF, as the render workers pose the links."""
        shapes = []
        for drawn in body.visuals:
            label, _ = body.annotated(drawn.link, drawn.visual.name)
            if label:
                skinned = drawn.visual if isinstance(drawn.visual.geometry, SkinnedMesh) else None
                shapes.append(Shape(drawn.link, label, visual_points(drawn.visual).astype(np.float64), skinned))
        tree = KinematicTree.of_urdf(body.urdf)
        children = {joint.child for joint in tree.joints}
        root = next(link for link in tree.links if link not in children)
        return BodyShapes(root, tree.joints, tuple(shapes))

    def links(self, base: Transform, positions: Mapping[str, float]) -> dict[str, Matrix]:
        """Each link's frame in the world, the root at `base`, the joints at `positions` (0 if absent)."""
        placed = {self.root: base.matrix()}
        pending = list(self.joints)
        while pending:
            ready = [joint for joint in pending if joint.parent in placed]
            if not ready:
                break
            for joint in ready:
                motion = _motion(joint, positions.get(joint.name, 0.0))
                placed[joint.child] = matmul(matmul(placed[joint.parent], joint.origin.matrix()), motion)
            pending = [joint for joint in pending if joint.child not in placed]
        return placed


def _motion(joint: UrdfJoint, position: float) -> Matrix:
    """A joint's own motion at `position`: a turn about its axis, or a slide along it."""
    out = np.eye(4)
    axis = np.asarray(joint.axis, dtype=float)
    axis = axis / (norm(axis) or 1.0)
    if joint.type in ("revolute", "continuous"):
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        out[:3, :3] = np.eye(3) + np.sin(position) * k + (1.0 - np.cos(position)) * matmul(k, k)
    elif joint.type == "prismatic":
        out[:3, 3] = axis * position
    return out


class View:
    """A camera at one pose: the world to its optical frame, and its pinhole projection."""

    def __init__(self, pose: Transform, spec: Optics) -> None:
        camera = pose.matrix()
        self.optical = np.eye(4)
        self.optical[:3, :3] = matmul(OPTICAL_FROM_CAMERA, camera[:3, :3].T)
        self.optical[:3, 3] = -matmul(self.optical[:3, :3], camera[:3, 3])
        self.fx = spec.fx
        self.cx, self.cy = spec.principal_point
        self.width, self.height, self.near = spec.width, spec.height, spec.near

    def to_optical(self, frame: Matrix, points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Points given in `frame` (a world pose), in the optical frame."""
        placed = matmul(self.optical, frame)
        out: npt.NDArray[np.float64] = matmul(points, placed[:3, :3].T) + placed[:3, 3]
        return out

    def project(self, optical: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """(u, v) of optical-frame points (in front of the camera)."""
        z = optical[:, 2]
        return np.stack([self.fx * optical[:, 0] / z + self.cx, self.fx * optical[:, 1] / z + self.cy], axis=1)

    def full(self, optical: npt.NDArray[np.float64]) -> Corners | None:
        """The projected extent of the points beyond the near clip, clipped to the image; None if empty."""
        ahead = optical[optical[:, 2] >= self.near]
        if not len(ahead):
            return None
        uv = self.project(ahead)
        u0, v0 = np.maximum(uv.min(axis=0), 0.0)
        u1, v1 = np.minimum(uv.max(axis=0), (self.width - 1, self.height - 1))
        return None if u0 > u1 or v0 > v1 else (float(u0), float(v0), float(u1), float(v1))


def visible(packed: npt.NDArray[np.uint32]) -> dict[Key, Corners]:
    """Each object's extent in the labels buffer, in pixel indices."""
    seen = labelled(packed) & (((packed >> 16) & 0xFF) != 0)
    rows, cols = np.nonzero(seen)
    if not len(rows):
        return {}
    keys = packed[rows, cols] & np.uint32(0xFFFFFF)
    order = np.argsort(keys, kind="stable")
    keys, rows, cols = keys[order], rows[order], cols[order]
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    extents = zip(
        keys[starts],
        np.minimum.reduceat(cols, starts),
        np.minimum.reduceat(rows, starts),
        np.maximum.reduceat(cols, starts),
        np.maximum.reduceat(rows, starts),
    )
    return {
        (int(key) & MAX_INSTANCE, int(key) >> 16): (float(u0), float(v0), float(u1), float(v1))
        for key, u0, v0, u1, v1 in extents
    }


@dataclass(frozen=True)
class Posed:
    """An object's vertices at the frame's instant: in the optical frame, and in its body's root frame."""

    optical: npt.NDArray[np.float64]
    local: npt.NDArray[np.float64]
    root: Matrix
    """The root link's world pose."""


class Objects:
    """The labelled objects of a camera's frames, with each body's shapes read once."""

    def __init__(self) -> None:
        self._read: dict[str, tuple[SceneBody, BodyShapes]] = {}

    def _shapes(self, body: SceneBody) -> BodyShapes:
        known = self._read.get(body.name)
        if known is None or known[0] is not body:
            known = self._read[body.name] = (body, BodyShapes.of(body))
        return known[1]

    def posed(self, frame: Frame, view: View, keys: list[Key]) -> dict[Key, Posed]:
        """The vertices of each object of `keys` (those of bodies no longer known are left out)."""
        by_instance = {body.instance: body for body in frame.bodies.values()}
        out = {}
        for instance, label in keys:
            body = by_instance.get(instance)
            if body is None:
                continue
            shapes = self._shapes(body)
            state = frame.states.get(body.name)
            links = shapes.links(state.base if state else body.base, state.joints if state else {})
            joints = state.joints if state else {}
            parts = [(links[s.link], _points(s, joints)) for s in shapes.shapes if s.label == label and s.link in links]
            if not parts:
                continue
            root_inverse = rigid_inverse(links[shapes.root])
            in_root = [(matmul(root_inverse, m), p) for m, p in parts]
            local = np.concatenate([matmul(p, m[:3, :3].T) + m[:3, 3] for m, p in in_root])
            optical = np.concatenate([view.to_optical(m, p) for m, p in parts])
            out[(instance, label)] = Posed(optical, local, links[shapes.root])
        return out

    def forget(self, names: set[str]) -> None:
        """Drops the shapes of bodies no longer in the scene."""
        for name in set(self._read) - names:
            del self._read[name]


def _points(shape: Shape, joints: Mapping[str, float]) -> npt.NDArray[np.float64]:
    """A shape's vertices at the frame's instant: a skin posed as its joints say."""
    if shape.skinned is None:
        return shape.points
    return np.asarray(visual_points(shape.skinned, joints), dtype=np.float64)


def draw_box(image: npt.NDArray[np.uint8], corners: Corners) -> None:
    """The outline of an axis-aligned box, one pixel wide, in Gazebo's green."""
    u0, v0, u1, v1 = (int(round(c)) for c in corners)
    image[v0 : v1 + 1, [u0, u1]] = GREEN
    image[[v0, v1], u0 : u1 + 1] = GREEN


def draw_segment(image: npt.NDArray[np.uint8], a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> None:
    """A line from pixel a to pixel b (u, v), what of it lies in the image."""
    steps = int(np.ceil(np.abs(b - a).max())) + 1
    uv = np.rint(np.linspace(a, b, steps)).astype(int)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < image.shape[1]) & (uv[:, 1] >= 0) & (uv[:, 1] < image.shape[0])
    image[uv[inside, 1], uv[inside, 0]] = GREEN
