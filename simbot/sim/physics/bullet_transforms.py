"""Transforms as the physics computes them: with PyBullet's own math, so that every float is the
one PyBullet's poses give (a pose composed in numpy differs in the last bits)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from simbot.description.poses import Pose
from simbot.sim.bullet import pb
from simbot.transform import Transform, Vec3


def pose_to_transform(pose: Pose) -> Transform:
    """(xyz, quaternion xyzw) of an SDF pose, PyBullet's pose form."""
    quat = pb.getQuaternionFromEuler(pose.rpy)
    return Transform(pose.xyz, (quat[0], quat[1], quat[2], quat[3]))


def compose(a: Transform, b: Transform) -> Transform:
    """a ∘ b."""
    return Transform.of(*pb.multiplyTransforms(a[0], a[1], b[0], b[1]))


def invert(a: Transform) -> Transform:
    """The inverse transform."""
    return Transform.of(*pb.invertTransform(a[0], a[1]))


def vec3(values: Sequence[float] | npt.NDArray[np.float64]) -> Vec3:
    return float(values[0]), float(values[1]), float(values[2])
