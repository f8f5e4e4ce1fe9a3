"""A camera's lens for clients that reproject images (the stitcher): the plumb_bob distortion D of
its camera_info (`simbot.bus.intrinsics.Intrinsics`), applied as OpenCV applies it, so a client
honours a bent lens (simbot's `<distortion>`) instead of assuming a pinhole."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from simbot.bus.intrinsics import BadInput, Intrinsics
from simbot.bus.tf_tree import Matrix

UNDISTORT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
"""cv2.undistortPoints's default 5 iterations are pixels short in the corners of a strong lens."""
NOWHERE = -1.0e9
"""An image coordinate far outside any image: where a ray the camera does not see is put."""


def undoable(info: Any) -> Intrinsics:
    """The intrinsics of a sensor_msgs/CameraInfo whose lens this module can undo; BadInput when it
    describes no camera, or a distortion other than plumb_bob's five coefficients (unless it is all zero)."""
    intrinsics = Intrinsics.from_info(info)
    if not intrinsics.plumb_bob:
        raise BadInput(
            f"camera_info distortion {intrinsics.distortion_model!r} D {list(intrinsics.d)}: only plumb_bob is undone"
        )
    return intrinsics


def pixels(camera: Intrinsics, x: Matrix, y: Matrix) -> tuple[Matrix, Matrix]:
    """The image points (u, v) of rays at normalised pinhole coordinates (x, y) (arrays of one
    shape), through the lens as cv2.projectPoints bends them. A ray wider than the image's widest
    (its corners' and edges' undistorted rays) is put NOWHERE: the polynomial could fold it back in."""
    if not any(camera.d):
        return camera.fx * x + camera.cx, camera.fy * y + camera.cy
    k, d = np.array([[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy], [0.0, 0.0, 1.0]]), np.array(camera.d)
    rays = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], axis=-1)
    uv = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, d)[0].reshape(*x.shape, 2)
    beyond = x * x + y * y > _widest(camera, k, d)
    return np.where(beyond, NOWHERE, uv[..., 0]), np.where(beyond, NOWHERE, uv[..., 1])


def _widest(camera: Intrinsics, k: Matrix, d: Matrix) -> float:
    """r² of the widest ray through the image's border pixels (every 4th, and the corners)."""
    w, h = camera.width - 1, camera.height - 1
    columns, rows = np.r_[0:w:4, w], np.r_[0:h:4, h]
    border = [(u, v) for u in columns for v in (0, h)] + [(u, v) for v in rows for u in (0, w)]
    rays = cv2.undistortPoints(np.array(border, dtype=np.float64).reshape(-1, 1, 2), k, d, criteria=UNDISTORT)
    return float((rays**2).sum(axis=-1).max())
