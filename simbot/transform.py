"""The one transform type of every layer: a frozen pose, position and quaternion, with its matrix.

The description (frames computed from SDF poses), the simulation (PyBullet's (xyz, xyzw) pairs),
the renderers (camera and body poses) and the bus (tf seen by the clients) all hold a rigid
transform as a `Transform`; 4×4 matrices and headings are made here and nowhere else, and so is
every rotation: a quaternion (always x, y, z, w) as a matrix and back, one or many at a time
(Shepperd's method, safe at a half turn), from roll, pitch and yaw or a heading alone, roll, pitch
and yaw as a matrix and back (SDF's and URDF's poses), or as turns about an axis (a skeleton's
keys, a BVH channel). PyBullet's own math stays with the physics (`sim/physics/bullet_transforms.py`),
so that its poses keep PyBullet's bits. Plain numpy, depending on nothing else in simbot, so that the bus
need not import the description layer (SPEC §7). A `Transform` is a tuple `(position, orientation)`: it unpacks as PyBullet's
pose pairs do and crosses process boundaries as plain data.

The products here (`matmul`, `norm`, `rigid_inverse`, `inverse3`) are what every published value
is computed with, in place of numpy's `@`, `dot` and `linalg`: those hand even a 3×3 product to
BLAS (OpenBLAS), whose kernel, and with it the order of a sum and its last bit, is chosen per
CPU at run time (`OPENBLAS_CORETYPE`). numpy's elementwise multiply and add round every operation
exactly as IEEE 754 says on any CPU, so a product summed term by term in index order gives the
same bits on an AVX-512 Xeon and an AVX2 EPYC (docs/reproducibility.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, overload

import numpy as np
import numpy.typing as npt
from numpy.typing import ArrayLike

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
"""x, y, z, w."""
Matrix = npt.NDArray[np.float64]

MANY_TERMS = 1024
"""Beyond this many products `matmul` makes the k-th terms only as it adds them, not every term in
one multiply first: a lidar's rays or an image's pixels then take half the time; a 4×4 is quicker
the other way. The same products and the same sums either way, so the same bits."""


@overload
def matmul(a: npt.NDArray[np.float32], b: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]: ...
@overload
def matmul(a: ArrayLike, b: ArrayLike) -> Matrix: ...
def matmul(a: ArrayLike, b: ArrayLike) -> npt.NDArray[np.floating]:
    """`a @ b` for a matrix (or a stack of rows) `a` and a matrix or vector `b`, each element summed
    term by term in index order, ((t0 + t1) + t2) + ...: the same bits on every CPU, where `@`
    would ask BLAS. The dtype is numpy's for `a * b` (float32 rows stay float32)."""
    left, right = np.asarray(a), np.asarray(b)
    if left.ndim == 2 and right.ndim == 1 and np.result_type(left, right) == np.float64:
        vector = right.tolist()
        return np.array([_dot(row, vector) for row in left.tolist()])
    if right.ndim == 1:
        if left.size > MANY_TERMS and left.shape[-1:] == right.shape:
            return _in_order(lambda k: left[..., k] * right[k], len(right))
        terms = left * right
        return _in_order(lambda k: terms[..., k], terms.shape[-1])
    if left.size * right.shape[-1] > MANY_TERMS and left.ndim >= 2 and left.shape[-1] == right.shape[-2]:
        return _in_order(lambda k: left[..., :, k, np.newaxis] * right[..., np.newaxis, k, :], right.shape[-2])
    terms = left[..., :, :, np.newaxis] * right[..., np.newaxis, :, :]
    return _in_order(lambda k: terms[..., k, :], terms.shape[-2])


def _dot(row: list[float], vector: list[float]) -> float:
    """Σ row[k]·vector[k] in Python floats (IEEE doubles, no fused multiply-add): a small matrix
    times a vector costs a third of numpy's per-call overhead this way."""
    total = row[0] * vector[0]
    for k in range(1, len(row)):
        total += row[k] * vector[k]
    return total


def _in_order(term: Callable[[int], Any], count: int) -> Any:
    """term(0) + term(1) + ... + term(count − 1), added one after the other."""
    total = term(0)
    for k in range(1, count):
        total = total + term(k)
    return total


def norm(vector: Sequence[float] | npt.NDArray[np.floating]) -> float:
    """The Euclidean length of a vector (`math.hypot`: correctly rounded, no BLAS)."""
    return math.hypot(*np.ravel(vector).tolist())


def rigid_inverse(matrix: Matrix) -> Matrix:
    """The inverse of a 4×4 rigid transform, (Rᵀ, −Rᵀt): exact where `np.linalg.inv` asks LAPACK."""
    given = np.asarray(matrix, dtype=float)
    rotation = given[:3, :3].T
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = -matmul(rotation, given[:3, 3])
    return out


def inverse3(matrix: Matrix) -> Matrix:
    """The inverse of a general 3×3 matrix (a scaled mesh's), from its cofactors: no LAPACK."""
    m = np.asarray(matrix, dtype=float)
    cofactors = np.array([np.cross(m[1], m[2]), np.cross(m[2], m[0]), np.cross(m[0], m[1])])
    determinant = float(matmul(m[0], cofactors[0]))
    if determinant == 0.0:
        raise ValueError("a singular 3×3 matrix has no inverse")
    return cofactors.T / determinant


def _rotation_rows(x: Any, y: Any, z: Any, w: Any) -> tuple[tuple[Any, Any, Any], ...]:
    """The rows of the rotation matrix of the unit quaternion (x, y, z, w): one formula for one
    quaternion (floats) and for many (arrays of each component)."""
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def quaternion_to_matrix(xyzw: Sequence[float]) -> Matrix:
    """Rotation matrix of a (normalised here) quaternion given as x, y, z, w."""
    length = norm(xyzw)
    x, y, z, w = (float(v) / length for v in xyzw)
    return np.array(_rotation_rows(x, y, z, w))


def quaternions_to_matrices(xyzw: Matrix) -> Matrix:
    """N×4 unit quaternions (x, y, z, w; not normalised here) as N×3×3 rotation matrices."""
    rows = _rotation_rows(xyzw[:, 0], xyzw[:, 1], xyzw[:, 2], xyzw[:, 3])
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def matrices_to_quaternions(rotations: ArrayLike) -> Matrix:
    """(…×3×3) rotation matrices as (…×4) quaternions x, y, z, w, by Shepperd's method: each from
    the largest of its trace and its diagonal, so that no component comes of dividing by a small one
    (a half turn included, whose w is 0)."""
    m = np.asarray(rotations, dtype=np.float64)
    diagonal = (m[..., 0, 0], m[..., 1, 1], m[..., 2, 2])
    trace = diagonal[0] + diagonal[1] + diagonal[2]
    largest = np.argmax(np.stack([trace, *diagonal], axis=-1), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):  # the cases not chosen may take a negative root
        s = 2.0 * np.sqrt(1.0 + trace)
        cases = [
            [
                (m[..., 2, 1] - m[..., 1, 2]) / s,
                (m[..., 0, 2] - m[..., 2, 0]) / s,
                (m[..., 1, 0] - m[..., 0, 1]) / s,
                s / 4,
            ]
        ]
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * np.sqrt(1.0 + m[..., i, i] - m[..., j, j] - m[..., k, k])
            case = [s / 4.0] * 4
            case[j], case[k] = (m[..., j, i] + m[..., i, j]) / s, (m[..., k, i] + m[..., i, k]) / s
            case[3] = (m[..., k, j] - m[..., j, k]) / s
            cases.append(case)
    stacked = np.stack([np.stack(case, axis=-1) for case in cases], axis=-2)
    chosen: Matrix = np.take_along_axis(stacked, largest[..., np.newaxis, np.newaxis], axis=-2)[..., 0, :]
    return chosen


def matrix_to_quaternion(rotation: ArrayLike) -> Quat:
    """The quaternion x, y, z, w of one 3×3 rotation matrix (`matrices_to_quaternions`)."""
    x, y, z, w = matrices_to_quaternions(rotation).tolist()
    return (x, y, z, w)


def rpy_to_quaternion(rpy: Sequence[float]) -> Quat:
    """The quaternion x, y, z, w of fixed-axis roll, pitch, yaw (R = Rz·Ry·Rx, as SDF and URDF write it)."""
    roll, pitch, yaw = (a / 2 for a in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def yaw_quaternion(yaw: float) -> Quat:
    """The quaternion x, y, z, w of an upright frame heading `yaw` (radians about z, REP-103)."""
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def axis_quaternion(axis: Sequence[float], angle: float) -> Quat:
    """The quaternion x, y, z, w of a turn by `angle` (radians) about the unit `axis` (a revolute joint's)."""
    s = math.sin(angle / 2)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2))


def rpy_to_matrix(rpy: Sequence[float]) -> Matrix:
    """R = Rz(yaw) Ry(pitch) Rx(roll), the convention of both SDF and URDF."""
    roll, pitch, yaw = rpy
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_rpy(rot: Matrix) -> Vec3:
    """Inverse of rpy_to_matrix; at gimbal lock the roll is folded into the yaw."""
    sp = -float(rot[2, 0])
    if abs(sp) >= 1.0 - 1e-12:
        pitch = math.copysign(math.pi / 2, sp)
        yaw = math.atan2(-float(rot[0, 1]), float(rot[1, 1]))
        return (0.0, pitch, yaw)
    pitch = math.asin(sp)
    roll = math.atan2(float(rot[2, 1]), float(rot[2, 2]))
    yaw = math.atan2(float(rot[1, 0]), float(rot[0, 0]))
    return (roll, pitch, yaw)


def axis_rotations(axis: Sequence[float] | npt.NDArray[np.floating], angles: ArrayLike) -> Matrix:
    """K×3×3 right-handed rotations about `axis` (normalised here) by each of `angles` (radians):
    k kᵀ + cos·(I − k kᵀ) + sin·[k]×, exact for an axis along x, y or z (1, cos and ±sin as they are)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / (norm(k) or 1.0)
    turns = np.atleast_1d(np.asarray(angles, dtype=np.float64))
    cos, sin = np.cos(turns)[:, None, None], np.sin(turns)[:, None, None]
    along = k[:, None] * k[None, :]
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    rotations: Matrix = along + cos * (np.eye(3) - along) + sin * cross
    return rotations


def rotate_into(xyzw: Sequence[float], vector: Sequence[float] | npt.NDArray[np.floating]) -> Vec3:
    """`vector`, given in the parent frame, in the frame whose orientation is the quaternion `xyzw`
    (normalised here): Rᵀv, as v + 2w(v × q) + 2q × (q × v) with q = (x, y, z) in Python floats.
    What a sensor does to every sample (an IMU's rates, a magnetometer's field), so it is cheap:
    no matrix is built, and no BLAS decides its last bit."""
    length = math.hypot(*xyzw)
    x, y, z, w = (float(c) / length for c in xyzw)
    vx, vy, vz = (float(c) for c in vector)
    # the conjugate rotation: t = 2 (v × q), Rᵀv = v + w t + t × q
    tx, ty, tz = 2.0 * (vy * z - vz * y), 2.0 * (vz * x - vx * z), 2.0 * (vx * y - vy * x)
    return (
        vx + w * tx + (ty * z - tz * y),
        vy + w * ty + (tz * x - tx * z),
        vz + w * tz + (tx * y - ty * x),
    )


def rotate_many(xyzw: npt.NDArray[np.float64], vectors: npt.NDArray[np.float64], *, into: bool = False) -> Matrix:
    """Each row of `vectors` (N×3) rotated by its row of quaternions (N×4, normalised here), or with
    `into` by its inverse: `rotate_into` for a fleet's sensors at once, in elementwise products."""
    qx, qy, qz, qw = xyzw[:, 0], xyzw[:, 1], xyzw[:, 2], xyzw[:, 3]
    length = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)  # summed in order: no CPU-chosen reduction
    x, y, z, w = qx / length, qy / length, qz / length, qw / length
    vx, vy, vz = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    sign = 1.0 if into else -1.0  # t = 2 (v × q) into the frame, 2 (q × v) out of it
    tx, ty, tz = sign * 2.0 * (vy * z - vz * y), sign * 2.0 * (vz * x - vx * z), sign * 2.0 * (vx * y - vy * x)
    out = np.empty_like(vectors, dtype=float)
    out[:, 0] = vx + w * tx + sign * (ty * z - tz * y)
    out[:, 1] = vy + w * ty + sign * (tz * x - tx * z)
    out[:, 2] = vz + w * tz + sign * (tx * y - ty * x)
    return out


def quaternion_products(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> Matrix:
    """Each row of `a` (N×4, xyzw; normalised here, as PyBullet's products are) times its row of
    `b`: rotation b then a, as `compose` turns frames, for a fleet's frames at once in elementwise
    products."""
    length = np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2] + a[:, 3] * a[:, 3])
    ax, ay, az, aw = a[:, 0] / length, a[:, 1] / length, a[:, 2] / length, a[:, 3] / length
    bx, by, bz, bw = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    return np.stack(
        [
            aw * bx + ax * bw + (ay * bz - az * by),
            aw * by + ay * bw + (az * bx - ax * bz),
            aw * bz + az * bw + (ax * by - ay * bx),
            aw * bw - (ax * bx + ay * by + az * bz),
        ],
        axis=1,
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
