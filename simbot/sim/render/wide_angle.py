"""A wide-angle lens (SDF `<lens>` of a `wideanglecamera`): Gazebo's mapping, drawn as a remap of cube faces.

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
drawn by the worker's own renderer (`views`), one after the other into a raw buffer (the
`wide_faces` output); the image is then one cv2.remap of those faces (`plan`: which face and
where, worked out once per camera). Gazebo's soft 0.02-wide edge at the cut-off is a hard one here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from simbot.sim.render.kinds import Array, Finish, Intrinsics, OutputKind, Raw
from simbot.sim.render.outputs import add_noise, luminance
from simbot.sim.render.specs import CameraSpec
from simbot.transform import Matrix, Transform, quaternion_to_matrix

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


def _plan_of(spec: Intrinsics) -> tuple[WideLens, Plan]:
    if not isinstance(spec, CameraSpec) or spec.wide is None:
        raise ValueError(f"a wide-angle output needs a camera with a wide-angle lens, got {spec!r}")
    return spec.wide, plan(spec.wide, spec.width, spec.height, spec.hfov)


class FacesKind(OutputKind):
    """The raw faces: each drawn face of `lens.face` pixels a side, one below the other."""

    def shape(self, spec: Intrinsics) -> tuple[int, ...]:
        lens, drawn = _plan_of(spec)
        return (len(drawn.faces) * lens.face, lens.face, 3)


def _remap(spec: Intrinsics) -> Callable[[Mapping[str, Array], Array], None]:
    """The camera's remap of its faces into an rgb image."""
    _, drawn = _plan_of(spec)

    def remap(arrays: Mapping[str, Array], out: Array) -> None:
        cv2.remap(arrays["wide_faces"], drawn.map1, drawn.map2, cv2.INTER_LINEAR, dst=out, borderValue=0)

    return remap


def _noise(spec: Intrinsics) -> Callable[[Array], None]:
    """The camera's seeded pixel noise, after the lens as on a real sensor."""
    rng = np.random.default_rng(spec.seed)

    def noise(pixels: Array) -> None:
        if spec.noise_stddev > 0.0:
            add_noise(pixels, spec.noise_stddev, rng)

    return noise


def color(spec: Intrinsics) -> Finish:
    """The faces remapped into the image, then the camera's pixel noise."""
    remap, noise = _remap(spec), _noise(spec)

    def finish(image: Array, arrays: Mapping[str, Array]) -> None:
        remap(arrays, image)
        noise(image)

    return finish


def mono(spec: Intrinsics) -> Finish:
    """As `color`, then to luminance (the faces are drawn in colour)."""
    remap, noise = _remap(spec), _noise(spec)
    rgb = np.empty((spec.height, spec.width, 3), dtype=np.uint8)

    def finish(image: Array, arrays: Mapping[str, Array]) -> None:
        remap(arrays, rgb)
        image[...] = luminance(rgb)
        noise(image)

    return finish


WIDE_FACES = FacesKind("wide_faces", np.uint8, 3, draws="color")
WIDE_COLOR = OutputKind("wide_color", np.uint8, 3, encoding="rgb8", needs=("wide_faces",), finisher=color)
WIDE_MONO = OutputKind("wide_mono", np.uint8, 1, encoding="mono8", needs=("wide_faces",), finisher=mono)


def views(
    spec: CameraSpec, pose: Transform, drawn: Mapping[Raw, Array]
) -> Iterator[tuple[Transform, dict[Raw, Array]]]:
    """What a renderer draws for a camera at `pose`: the pose and its buffers once for a pinhole
    camera; each face's pose and its slice of the raw faces for a wide-angle one (`spec.rendered`
    is the face's camera)."""
    if spec.wide is None:
        yield pose, dict(drawn)
        return
    lens, drawn_plan = spec.wide, plan(spec.wide, spec.width, spec.height, spec.hfov)
    faces = drawn["color"].reshape(len(drawn_plan.faces), lens.face, lens.face, 3)
    body = quaternion_to_matrix(pose.orientation)
    for slot, index in enumerate(drawn_plan.faces):
        rotation = body @ OPTICAL_IN_CAMERA @ FACES[index] @ OPTICAL_IN_CAMERA.T
        yield Transform(pose.position, _quaternion(rotation)), {"color": faces[slot]}


def _quaternion(m: Matrix) -> tuple[float, float, float, float]:
    """x, y, z, w of a rotation matrix (Shepperd's method: the largest of the four first)."""
    trace = float(np.trace(m))
    candidates = [trace, m[0, 0], m[1, 1], m[2, 2]]
    largest = int(np.argmax(candidates))
    if largest == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4.0)
    else:
        i = largest - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        v = [0.0, 0.0, 0.0]
        v[i], v[j], v[k] = s / 4.0, (m[j, i] + m[i, j]) / s, (m[k, i] + m[i, k]) / s
        q = (v[0], v[1], v[2], (m[k, j] - m[j, k]) / s)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
