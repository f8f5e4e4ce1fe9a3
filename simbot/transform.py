"""The one transform type of every layer: a frozen pose, position and quaternion, with its matrix.

The description (frames computed from SDF poses), the simulation (PyBullet's (xyz, xyzw) pairs),
the renderers (camera and body poses) and the bus (tf seen by the clients) all hold a rigid
transform as a `Transform`; 4×4 matrices and headings are made here and nowhere else. Plain
numpy, depending on nothing else in simbot, so that the bus need not import the description
layer (SPEC §7). A `Transform` is a tuple `(position, orientation)`: it unpacks as PyBullet's
pose pairs do and crosses process boundaries as plain data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
"""x, y, z, w."""
Matrix = npt.NDArray[np.float64]


def quaternion_to_matrix(xyzw: Sequence[float]) -> Matrix:
    """Rotation matrix of a (normalised here) quaternion given as x, y, z, w."""
    x, y, z, w = np.asarray(xyzw, dtype=float) / np.linalg.norm(xyzw)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def yaw_of(xyzw: Sequence[float]) -> float:
    """Heading (rotation about z, REP-103) of an xyzw quaternion, radians in (−π, π]."""
    x, y, z, w = xyzw
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class Transform(NamedTuple):
    """A rigid transform: a frame's position and orientation (quaternion x, y, z, w) in its parent."""

    position: Vec3 = (0.0, 0.0, 0.0)
    orientation: Quat = (0.0, 0.0, 0.0, 1.0)

    @staticmethod
    def of(position: Sequence[float], orientation: Sequence[float]) -> Transform:
        """From any sequences of floats (PyBullet's lists, numpy arrays)."""
        x, y, z = position
        qx, qy, qz, qw = orientation
        return Transform((float(x), float(y), float(z)), (float(qx), float(qy), float(qz), float(qw)))

    def matrix(self) -> Matrix:
        """The 4×4 homogeneous matrix."""
        out = np.eye(4)
        out[:3, :3] = quaternion_to_matrix(self.orientation)
        out[:3, 3] = self.position
        return out

    @property
    def yaw(self) -> float:
        return yaw_of(self.orientation)
