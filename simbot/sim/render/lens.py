"""Lens distortion (SDF `<distortion>`): the image a real plumb_bob lens sees, made from a pinhole render.

The published image is bent by the Brown–Conrady model that ROS calls `plumb_bob` and OpenCV
uses: a ray whose pinhole (undistorted) normalised coordinates are (x, y), r² = x² + y², lands at

    x' = x·(1 + k1·r² + k2·r⁴ + k3·r⁶) + 2·p1·x·y + p2·(r² + 2x²)
    y' = y·(1 + k1·r² + k2·r⁴ + k3·r⁶) + p1·(r² + 2y²) + 2·p2·x·y

and is seen at pixel (fx·x' + cx, fy·y' + cy) of the published K. So `cv2.undistortPoints` with
the published K and D = [k1, k2, p1, p2, k3] maps image points back onto the pinhole image
(lines straight). Gazebo's own distortion pass applies the same formula in the same direction,
but then scales the bent image to crop its black corners, which its camera_info does not follow;
simbot does not crop.

`<center>` is the distortion centre in normalised image coordinates (0..1 across the image's
width and height, (0.5, 0.5) its middle), as Gazebo reads it. plumb_bob has no centre of its own:
its distortion is about K's principal point, so the principal point is put there,
cx = center_x·width − 0.5, cy = center_y·height − 0.5 (pixel-centre coordinates: (0.5, 0.5) gives
the image centre ((w−1)/2, (h−1)/2) as for a pinhole camera). Gazebo keeps cx, cy at the image
centre whatever `<center>` says, so its camera_info does not undistort an off-centre lens; simbot's
does. A `<distortion>` whose five coefficients are all zero is no lens (Gazebo skips it too):
K, the render and the image are the pinhole camera's, whatever `<center>` says.

How it is drawn: the renderer draws a pinhole image of the same size with its own focal length
(`render_focal`: the field the lens's rays need, a wider one for barrel distortion, a narrower
one for pincushion); each output pixel samples the render where its undistorted ray lands
(`Remap`: cv2.undistortPoints of the pixel grid, once per camera in its worker), applied per frame
with cv2.remap: bilinear for colour, nearest for depth so that no depth is invented across an
edge. A pixel whose ray no render can hold (the lens folds back on itself there, or the ray is
more than 85° off the axis) reads black in colour and +inf in depth, as no light reaches it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, TypeVar

import cv2
import numpy as np
import numpy.typing as npt

Floats = npt.NDArray[np.float32]
Image = TypeVar("Image", npt.NDArray[np.uint8], npt.NDArray[np.float32])
NO_FRACTIONS = np.empty(0, dtype=np.uint16)
"""The interpolation table nearest-neighbour remap does without."""
MAX_HALF_FOV = math.radians(85.0)
"""The widest half field a render may draw (a perspective projection cannot reach 90°)."""
ITERATIONS = (20, 300)
"""cv2.undistortPoints's fixed-point iterations: a first pass for every pixel (its default 5 leave ~2 px
in the corners at k1 = −0.25), then a long one for the pixels the first leaves short (a strong lens)."""
HIT_PX = 0.01
"""A ray is the pixel's when the lens (`distort`) puts it within this of the pixel."""


@dataclass(frozen=True)
class Distortion:
    """SDF `<distortion>`: plumb_bob coefficients and the centre (module docstring)."""

    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    center: tuple[float, float] = (0.5, 0.5)

    @property
    def bends(self) -> bool:
        """Whether it changes the image at all."""
        return any(c != 0.0 for c in self.d)

    @property
    def d(self) -> tuple[float, float, float, float, float]:
        """D of sensor_msgs/CameraInfo for plumb_bob, in ROS's (and OpenCV's) order."""
        return (self.k1, self.k2, self.p1, self.p2, self.k3)


def principal_point(distortion: Distortion, width: int, height: int) -> tuple[float, float]:
    """(cx, cy) in pixel-centre coordinates: the distortion centre of a lens that bends, else the image centre."""
    cx, cy = distortion.center if distortion.bends else (0.5, 0.5)
    return cx * width - 0.5, cy * height - 0.5


def _camera_matrix(fx: float, cx: float, cy: float) -> npt.NDArray[np.float64]:
    return np.array([[fx, 0.0, cx], [0.0, fx, cy], [0.0, 0.0, 1.0]])


def distort(distortion: Distortion, ray: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Where the lens bends normalised pinhole rays (N×2): the module docstring's formula."""
    x, y = ray[:, 0], ray[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (distortion.k1 + r2 * (distortion.k2 + r2 * distortion.k3))
    p1, p2 = distortion.p1, distortion.p2
    bent_x = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    bent_y = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([bent_x, bent_y], axis=-1)


@cache
def rays(distortion: Distortion, width: int, height: int, fx: float) -> tuple[Floats, Floats]:
    """The undistorted normalised ray (x, y) of every published pixel (H×W each), by
    cv2.undistortPoints; NaN where none is (the lens puts no ray within HIT_PX of the pixel)."""
    cx, cy = principal_point(distortion, width, height)
    k, d = _camera_matrix(fx, cx, cy), np.array(distortion.d)
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pixels = np.stack([u.ravel(), v.ravel()], axis=-1)
    normalised = (pixels - (cx, cy)) / fx
    ray = np.empty_like(pixels)
    short = np.ones(len(pixels), dtype=bool)
    for count in ITERATIONS:
        if not short.any():
            break
        solve = (cv2.TERM_CRITERIA_COUNT, count, 0.0)
        ray[short] = cv2.undistortPoints(pixels[short].reshape(-1, 1, 2), k, d, criteria=solve).reshape(-1, 2)
        short = np.linalg.norm(distort(distortion, ray) - normalised, axis=1) * fx >= HIT_PX
    ray[short | np.any(np.abs(ray) >= math.tan(MAX_HALF_FOV), axis=1)] = np.nan
    x, y = ray[:, 0].reshape(height, width), ray[:, 1].reshape(height, width)
    return x.astype(np.float32), y.astype(np.float32)


@cache
def render_focal(distortion: Distortion, width: int, height: int, fx: float) -> float:
    """The focal length (px) of the pinhole render a lens samples: the largest whose image, of the
    published size with a symmetric frustum, holds every pixel's ray (centre of the edge pixels
    included, so bilinear sampling stays inside)."""
    x, y = rays(distortion, width, height, fx)
    reach_x, reach_y = np.nanmax(np.abs(x), initial=0.0), np.nanmax(np.abs(y), initial=0.0)
    widest = (width / 2.0) / math.tan(MAX_HALF_FOV)
    fits = [half / reach for half, reach in (((width - 1) / 2.0, reach_x), ((height - 1) / 2.0, reach_y)) if reach > 0]
    return max(widest, min(fits, default=fx))


class Remap:
    """A camera's lens as cv2.remap tables from its pinhole render, and the scratch copy a remap reads."""

    def __init__(self, distortion: Distortion, width: int, height: int, fx: float) -> None:
        x, y = rays(distortion, width, height, fx)
        focal = render_focal(distortion, width, height, fx)
        # no ray: far outside the render, so the border value is read
        map_x = np.nan_to_num(x * focal + (width - 1) / 2.0, nan=-width).astype(np.float32)
        map_y = np.nan_to_num(y * focal + (height - 1) / 2.0, nan=-height).astype(np.float32)
        self.linear = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        self.nearest = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2, nninterpolation=True)[0], NO_FRACTIONS
        self._scratch: dict[tuple[tuple[int, ...], str], npt.NDArray[Any]] = {}

    def _source(self, image: Image) -> Image:
        """The render copied aside: the remap writes the published image over it."""
        key = (image.shape, image.dtype.str)
        scratch = self._scratch.get(key)
        if scratch is None:
            scratch = self._scratch[key] = np.empty_like(image)
        np.copyto(scratch, image)
        return scratch

    def pixels(self, image: npt.NDArray[np.uint8]) -> None:
        """Colour (H×W×3) or luminance (H×W), in place: bilinear, black where no ray is."""
        map1, map2 = self.linear
        cv2.remap(self._source(image), map1, map2, cv2.INTER_LINEAR, dst=image, borderMode=cv2.BORDER_CONSTANT)

    def depth(self, depth: Floats) -> None:
        """Metres, in place: the nearest render pixel's, +inf where no ray is."""
        map1, map2 = self.nearest
        cv2.remap(
            self._source(depth),
            map1,
            map2,
            cv2.INTER_NEAREST,
            dst=depth,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=math.inf,
        )


@cache
def remap(distortion: Distortion, width: int, height: int, fx: float) -> Remap:
    """One `Remap` per camera geometry in a worker: its colour, depth and points share it."""
    return Remap(distortion, width, height, fx)
