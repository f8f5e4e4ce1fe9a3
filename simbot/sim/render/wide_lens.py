"""A wide-angle lens (SDF `<lens>` of a `wideanglecamera`): Gazebo's mapping, and the remap of cube
faces that draws it (the output kinds and the views a renderer draws are in `wide_angle.py`).

Gazebo's WideAngleCamera puts a ray θ off the optical axis at the distance

    r = c1 · f · fun(θ / c2 + c3)        fun: sin, tan or id

from the image centre, r in units of half the image's width (so a pixel's f is f · width / 2).
The named lens types are custom functions (c1, c2, c3, f, fun): gnomonical (1, 1, 0, 1, tan, the
pinhole), stereographic (2, 2, 0, 1, tan), equidistant (1, 1, 0, 1, id), equisolid_angle
(2, 2, 0, 1, sin), orthographic (1, 1, 0, 1, sin). With `<scale_to_hfov>` (the default) f is
replaced by the one that puts θ = hfov/2 at the image's left and right edges, f = 1 / (c1 ·
fun(hfov / 2 / c2 + c3)). A pixel's ray is found by inverting it, θ = (fun⁻¹(r / (c1·f)) − c3) · c2,
and it looks along (sin θ · x/r, sin θ · y/r, cos θ) in the optical frame; a pixel whose ray lies
beyond `<cutoff_angle>` (or that the function cannot reach: asin of more than 1) is black.

How it is drawn: Gazebo renders a cube map of `<env_texture_size>` a face and samples it per
pixel. simbot draws only the cube faces some pixel looks into (a 180° lens needs five, a 120°
one the front face and the four beside it only in part), each a 90° pinhole view of that size
drawn by the worker's own renderer (`wide_angle.views`), one after the other into a raw buffer (the
`wide_faces` output); the image is then one cv2.remap of those faces (`plan`: which face and
where, worked out once per camera). Gazebo's soft 0.02-wide edge at the cut-off is a hard one here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from simbot.transform import Matrix

Floats = npt.NDArray[np.float64]
Function = Callable[[Floats], Floats]

FUNCTIONS: dict[str, tuple[Function, Function]] = {
    "sin": (np.sin, np.arcsin),
    "tan": (np.tan, np.arctan),
    "id": (np.asarray, np.asarray),
}
"""Gazebo's angle functions by their SDF name, each with its inverse."""
LENS_TYPES: dict[str, tuple[float, float, float, float, str]] = {
    "gnomonical": (1.0, 1.0, 0.0, 1.0, "tan"),
    "stereographic": (2.0, 2.0, 0.0, 1.0, "tan"),
    "equidistant": (1.0, 1.0, 0.0, 1.0, "id"),
    "equisolid_angle": (2.0, 2.0, 0.0, 1.0, "sin"),
    "orthographic": (1.0, 1.0, 0.0, 1.0, "sin"),
}
"""(c1, c2, c3, f, fun) of each named lens type, as gz-rendering's CameraLens sets them; `custom` reads its own."""


@dataclass(frozen=True)
class WideLens:
    """SDF `<lens>`: the mapping function, its scaling, the cut-off and the cube face size."""

    type: str = "stereographic"
    c1: float = 2.0
    c2: float = 2.0
    c3: float = 0.0
    f: float = 1.0
    fun: str = "tan"
    scale_to_hfov: bool = True
    cutoff: float = math.pi / 2
    face: int = 256
    """`<env_texture_size>`: pixels on a side of each cube face drawn."""

    def focal(self, hfov: float) -> float:
        """f in units of half the image width: the SDF's, or the one that fits hfov to the width."""
        if not self.scale_to_hfov:
            return self.f
        forward, _ = FUNCTIONS[self.fun]
        return float(1.0 / (self.c1 * forward(np.float64(hfov / 2.0 / self.c2 + self.c3))))

    def focal_px(self, width: int, hfov: float) -> float:
        """f in pixels: the K of its camera_info."""
        return self.focal(hfov) * width / 2.0

    def radius(self, theta: Floats, focal_px: float) -> Floats:
        """Pixels from the image centre of rays `theta` radians off the axis: the module docstring's r."""
        forward, _ = FUNCTIONS[self.fun]
        return self.c1 * focal_px * forward(np.asarray(theta) / self.c2 + self.c3)

    def angle(self, radius: Floats, focal_px: float) -> Floats:
        """The ray angle of pixels `radius` from the centre (NaN where the function cannot reach)."""
        _, inverse = FUNCTIONS[self.fun]
        with np.errstate(invalid="ignore"):
            return (inverse(np.asarray(radius) / (self.c1 * focal_px)) - self.c3) * self.c2


def _face(right: tuple[int, int, int], down: tuple[int, int, int]) -> Matrix:
    """A face's axes in the camera's optical frame, as columns: right, down, forward."""
    r, d = np.array(right, dtype=float), np.array(down, dtype=float)
    return np.column_stack([r, d, np.cross(r, d)])


FACES = (
    _face((1, 0, 0), (0, 1, 0)),  # front
    _face((0, 0, -1), (0, 1, 0)),  # right
    _face((0, 0, 1), (0, 1, 0)),  # left
    _face((1, 0, 0), (0, 0, -1)),  # down
    _face((1, 0, 0), (0, 0, 1)),  # up
    _face((-1, 0, 0), (0, 1, 0)),  # back
)
"""The cube's six 90° views in the optical frame (x right, y down, z forward)."""
OPTICAL_IN_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""The optical frame's axes in the SDF camera frame (x forward, y left, z up), as columns."""


@dataclass(frozen=True)
class Plan:
    """What a wide-angle camera draws and how its image is made of it."""

    faces: tuple[int, ...]
    """Indices into FACES of the faces some pixel looks into, in the order they lie in the raw buffer."""
    map1: npt.NDArray[Any]
    map2: npt.NDArray[Any]
    """cv2.remap tables (fixed point) from the stacked faces to the image."""


def rays(lens: WideLens, width: int, height: int, hfov: float) -> tuple[Floats, npt.NDArray[np.bool_]]:
    """Each pixel's unit ray in the optical frame (H×W×3), and where it is seen (within the cut-off)."""
    focal = lens.focal_px(width, hfov)
    x, y = np.meshgrid(np.arange(width) - (width - 1) / 2.0, np.arange(height) - (height - 1) / 2.0)
    radius = np.hypot(x, y)
    theta = lens.angle(radius, focal)
    seen = np.isfinite(theta) & (theta <= lens.cutoff)
    theta = np.where(seen, theta, 0.0)
    scale = np.divide(np.sin(theta), radius, out=np.zeros_like(radius), where=radius > 0)
    return np.stack([x * scale, y * scale, np.cos(theta)], axis=-1), seen


@cache
def plan(lens: WideLens, width: int, height: int, hfov: float) -> Plan:
    """Which faces to draw, and where in them each pixel's ray lands (once per camera geometry)."""
    ray, seen = rays(lens, width, height, hfov)
    local = np.einsum("hwi,fij->fhwj", ray, np.stack(FACES))  # each ray in each face's axes
    face = np.argmax(local[..., 2], axis=0)
    faces = tuple(int(f) for f in np.unique(face[seen]))
    slot = np.zeros(len(FACES), dtype=int)
    slot[list(faces)] = np.arange(len(faces))
    along = np.take_along_axis(local, face[np.newaxis, ..., np.newaxis], axis=0)[0]
    size = lens.face
    u = np.clip(size / 2.0 * along[..., 0] / along[..., 2] + (size - 1) / 2.0, 0, size - 1)
    v = np.clip(size / 2.0 * along[..., 1] / along[..., 2] + (size - 1) / 2.0, 0, size - 1) + slot[face] * size
    map_x = np.where(seen, u, -size).astype(np.float32)  # unseen: outside the faces, read as black
    map_y = np.where(seen, v, -size).astype(np.float32)
    map1, map2 = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
    return Plan(faces, map1, map2)
