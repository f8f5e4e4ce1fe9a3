"""Pose algebra: the rpy convention shared by SDF and URDF, composition and inversion, poses from transforms."""

from __future__ import annotations

import math

import numpy as np

from simbot.description.poses import Pose, matrix_to_rpy, rpy_to_matrix
from simbot.transform import Transform, quaternion_to_matrix


def test_rpy_is_fixed_axis_xyz() -> None:
    """R(rpy) = Rz(yaw) Ry(pitch) Rx(roll): yaw 90° turns x onto y, roll 90° turns y onto z."""
    assert np.allclose(rpy_to_matrix((0, 0, math.pi / 2)) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(rpy_to_matrix((math.pi / 2, 0, 0)) @ [0, 1, 0], [0, 0, 1])
    assert np.allclose(rpy_to_matrix((0, math.pi / 2, 0)) @ [0, 0, 1], [1, 0, 0])


def test_rpy_round_trip() -> None:
    """matrix_to_rpy inverts rpy_to_matrix away from gimbal lock, and keeps the rotation at it."""
    rng = np.random.default_rng(7)
    for rpy in rng.uniform([-math.pi, -1.5, -math.pi], [math.pi, 1.5, math.pi], size=(200, 3)):
        assert np.allclose(matrix_to_rpy(rpy_to_matrix(tuple(rpy))), rpy, atol=1e-9)
    locked = rpy_to_matrix((0.3, math.pi / 2, 0.2))
    assert np.allclose(rpy_to_matrix(matrix_to_rpy(locked)), locked, atol=1e-9)


def test_compose_and_invert() -> None:
    """a_T_b @ b_T_c moves a point as the two transforms in turn; p @ p⁻¹ is the identity."""
    a = Pose((1.0, 2.0, 3.0), (0.1, -0.2, 0.3))
    b = Pose((-0.5, 0.0, 0.25), (0.0, 0.4, -1.0))
    point = np.array([0.3, -0.7, 1.1, 1.0])
    assert np.allclose((a @ b).matrix() @ point, a.matrix() @ (b.matrix() @ point))
    assert (a @ a.inverse()).is_identity(1e-12)


def test_quaternion() -> None:
    """A quaternion of 90° about z is the same rotation as yaw 90°."""
    s = math.sqrt(0.5)
    assert np.allclose(quaternion_to_matrix((0.0, 0.0, s, s)), rpy_to_matrix((0, 0, math.pi / 2)))


def test_pose_from_transform() -> None:
    """A position and a quaternion of 90° about z are the pose at that position with yaw 90°."""
    s = math.sqrt(0.5)
    pose = Pose.from_transform(Transform((1.0, 2.0, 3.0), (0.0, 0.0, s, s)))
    assert np.allclose(pose.matrix(), Pose((1.0, 2.0, 3.0), (0.0, 0.0, math.pi / 2)).matrix())
