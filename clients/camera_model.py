"""A camera as its sensor_msgs/CameraInfo describes it, for clients that reproject images (the
stitcher): image size, K, and the plumb_bob lens distortion D, applied as OpenCV applies it, so a
client honours a bent lens (simbot's `<distortion>`) instead of assuming a pinhole."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from simbot.bus.transforms import Matrix

UNDISTORT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
"""cv2.undistortPoints's default 5 iterations are pixels short in the corners of a strong lens."""
NOWHERE = -1.0e9
"""An image coordinate far outside any image: where a ray the camera does not see is put."""


class BadInput(ValueError):
    """An image or camera_info that cannot be used (encoding, size, intrinsics); str() is one line."""


@dataclass(frozen=True)
class Intrinsics:
    """A camera's frame, image size, K and plumb_bob D (k1, k2, p1, p2, k3), from its camera_info."""

    frame_id: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    d: tuple[float, ...] = (0.0,) * 5

    @classmethod
    def from_info(cls, info: Any) -> Intrinsics:
        """The intrinsics of a sensor_msgs/CameraInfo; BadInput when it describes no usable camera
        (a distortion other than plumb_bob's five coefficients, unless it is all zero)."""
        k = [float(v) for v in info.k]
        fx, fy, cx, cy = k[0], k[4], k[2], k[5]
        if info.width < 1 or info.height < 1:
            raise BadInput(f"camera_info size {info.width}×{info.height}")
        if not (fx > 0 and fy > 0 and all(math.isfinite(v) for v in (fx, fy, cx, cy))):
            raise BadInput(f"camera_info K has fx {fx}, fy {fy}, cx {cx}, cy {cy}")
        d = tuple(float(v) for v in info.d) if any(info.d) else (0.0,) * 5
        if len(d) != 5 or info.distortion_model != "plumb_bob" or not all(map(math.isfinite, d)):
            raise BadInput(f"camera_info distortion {info.distortion_model!r} D {list(d)}: only plumb_bob is undone")
        return cls(info.header.frame_id.lstrip("/"), int(info.width), int(info.height), fx, fy, cx, cy, d)

    def pixels(self, x: Matrix, y: Matrix) -> tuple[Matrix, Matrix]:
        """The image points (u, v) of rays at normalised pinhole coordinates (x, y) (arrays of one
        shape), through the lens as cv2.projectPoints bends them. A ray wider than the image's widest
        (its corners' and edges' undistorted rays) is put NOWHERE: the polynomial could fold it back in."""
        if not any(self.d):
            return self.fx * x + self.cx, self.fy * y + self.cy
        k, d = np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]]), np.array(self.d)
        rays = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], axis=-1)
        uv = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, d)[0].reshape(*x.shape, 2)
        beyond = x * x + y * y > self._widest(k, d)
        return np.where(beyond, NOWHERE, uv[..., 0]), np.where(beyond, NOWHERE, uv[..., 1])

    def _widest(self, k: Matrix, d: Matrix) -> float:
        """r² of the widest ray through the image's border pixels (every 4th, and the corners)."""
        w, h = self.width - 1, self.height - 1
        columns, rows = np.r_[0:w:4, w], np.r_[0:h:4, h]
        border = [(u, v) for u in columns for v in (0, h)] + [(u, v) for v in rows for u in (0, w)]
        rays = cv2.undistortPoints(np.array(border, dtype=np.float64).reshape(-1, 1, 2), k, d, criteria=UNDISTORT)
        return float((rays**2).sum(axis=-1).max())
