"""Rigid transforms as SDF and URDF write them: xyz plus fixed-axis roll, pitch, yaw (their rotation
arithmetic is `simbot.transform`'s)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbot.transform import Transform, matmul, matrix_to_rpy, rigid_inverse, rpy_to_matrix

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Pose:
    """A frame's placement in its parent frame."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @staticmethod
    def from_matrix(mat: np.ndarray) -> Pose:
        """The pose of a 4x4 homogeneous transform."""
        x, y, z = (float(v) for v in mat[:3, 3])
        return Pose((x, y, z), matrix_to_rpy(mat[:3, :3]))

    @staticmethod
    def from_transform(transform: Transform) -> Pose:
        """The pose of a position and quaternion (SDF's `quat_xyzw` poses, the create service's poses)."""
        return Pose.from_matrix(transform.matrix())

    def matrix(self) -> np.ndarray:
        """The 4x4 homogeneous transform parent_T_frame."""
        mat = np.eye(4)
        mat[:3, :3] = rpy_to_matrix(self.rpy)
        mat[:3, 3] = self.xyz
        return mat

    def __matmul__(self, other: Pose) -> Pose:
        """Composition: (a_T_b @ b_T_c) is a_T_c."""
        return Pose.from_matrix(matmul(self.matrix(), other.matrix()))

    def inverse(self) -> Pose:
        """b_T_a from a_T_b."""
        return Pose.from_matrix(rigid_inverse(self.matrix()))

    def is_identity(self, tol: float = 1e-12) -> bool:
        """True when the frame coincides with its parent."""
        return bool(np.allclose(self.matrix(), np.eye(4), atol=tol))


IDENTITY = Pose()
