"""Quaternion arithmetic that every layer needs: plain numpy, depending on nothing else in simbot.

The description layer (SDF poses) and the bus layer (tf seen by the clients) both turn x, y, z, w
quaternions into rotation matrices and headings; this leaf module lets them share one copy
without the bus importing the description layer (SPEC §7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def quaternion_to_matrix(xyzw: Sequence[float]) -> np.ndarray:
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
