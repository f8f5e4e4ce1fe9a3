"""Pose algebra: the rpy convention shared by SDF and URDF, composition and inversion, poses from
transforms; and simbot.transform's rotations, the one home of quaternions and turns."""

from __future__ import annotations

import math

import numpy as np

from simbot.description.poses import Pose, matrix_to_rpy, rpy_to_matrix
from simbot.transform import (
    Transform,
    axis_rotations,
    matrices_to_quaternions,
    matrix_to_quaternion,
    quaternion_to_matrix,
    quaternions_to_matrices,
    rpy_to_quaternion,
)


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


def _random_quaternions(count: int, seed: int) -> np.ndarray:
    """Unit quaternions x, y, z, w, uniform over rotations, w ≥ 0."""
    q = np.random.default_rng(seed).normal(size=(count, 4))
    q /= np.sqrt((q * q).sum(axis=1))[:, None]
    return q * np.where(q[:, 3:] < 0, -1.0, 1.0)


def test_a_quaternion_comes_back_from_its_matrix_one_or_many_at_a_time() -> None:
    """Matrix → quaternion inverts quaternion → matrix (up to the sign, fixed here by w ≥ 0); the
    one-at-a-time and the many-at-a-time forms agree (the quaternion from a matrix to the bit: one
    formula; the matrix of a quaternion to its last bits: the single one is normalised first)."""
    quats = _random_quaternions(500, 3)
    matrices = quaternions_to_matrices(quats)
    back = matrices_to_quaternions(matrices)
    back *= np.where(back[:, 3:] < 0, -1.0, 1.0)
    assert np.allclose(back, quats, atol=1e-12)
    for q, m in zip(quats[:20], matrices[:20]):
        assert np.allclose(quaternion_to_matrix(q), m, rtol=0.0, atol=1e-14)
        assert matrix_to_quaternion(m) == tuple(matrices_to_quaternions(m).tolist())


def test_a_half_turn_keeps_its_axis() -> None:
    """A half turn (w = 0) about an axis with two nonzero components keeps their relative sign:
    (1, 0, −1)/√2 is not (1, 0, 1)/√2, which a quaternion read from the trace alone cannot tell."""
    for axis in ((1.0, 0.0, -1.0), (1.0, 0.0, 1.0), (0.0, -1.0, 1.0), (1.0, -1.0, 0.0)):
        turn = axis_rotations(axis, math.pi)[0]
        x, y, z, w = matrix_to_quaternion(turn)
        assert np.allclose(quaternion_to_matrix((x, y, z, w)), turn, atol=1e-12)
        assert abs(w) < 1e-12


def test_turns_about_an_axis_are_rodrigues_and_exact_about_x_y_z() -> None:
    """A turn about any axis rotates that axis onto itself and a perpendicular by the angle; about
    x, y or z its matrix holds 1, cos and ±sin exactly, as a BVH channel's turn is written."""
    angles = np.linspace(-7.0, 7.0, 57)
    axis = np.array([0.3, -0.5, 0.8]) / math.sqrt(0.98)
    turns = axis_rotations(axis, angles)
    assert np.allclose(turns @ axis, np.tile(axis, (len(angles), 1)), atol=1e-12)
    across = np.cross(axis, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    assert np.allclose((turns @ across) @ across, np.cos(angles), atol=1e-12)
    cos, sin = np.cos(angles), np.sin(angles)
    about_y = axis_rotations((0.0, 1.0, 0.0), angles)
    assert np.array_equal(about_y[:, 1, 1], np.ones_like(angles))
    assert np.array_equal(about_y[:, 0, 0], cos) and np.array_equal(about_y[:, 2, 2], cos)
    assert np.array_equal(about_y[:, 0, 2], sin) and np.array_equal(about_y[:, 2, 0], -sin)


def test_roll_pitch_yaw_as_a_quaternion_is_the_rpy_rotation() -> None:
    rng = np.random.default_rng(11)
    for rpy in rng.uniform(-math.pi, math.pi, size=(100, 3)):
        quat = rpy_to_quaternion(tuple(rpy))
        assert np.allclose(quaternion_to_matrix(quat), rpy_to_matrix(tuple(rpy)), atol=1e-12)
