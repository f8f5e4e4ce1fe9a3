"""nav_msgs: the odometry of a drive (its pose and twist, each with a covariance)."""

from __future__ import annotations

from simbot.bus.messages.geometry import pose, twist
from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import Odometry, PoseWithCovariance, TwistWithCovariance
from simbot.bus.messages.values import Floats, float_array

COVARIANCE_SIZE = 36


def odometry(
    ns: int,
    frame_id: str,
    child_frame_id: str,
    xyz: Floats,
    quat_xyzw: Floats,
    linear_xyz: Floats,
    angular_xyz: Floats,
    pose_covariance: Floats = (0.0,) * COVARIANCE_SIZE,
    twist_covariance: Floats = (0.0,) * COVARIANCE_SIZE,
) -> Odometry:
    """nav_msgs/Odometry: pose in `frame_id`, twist in `child_frame_id`, 6×6 row-major covariances."""
    return Odometry(
        header=header(ns, frame_id),
        child_frame_id=child_frame_id,
        pose=PoseWithCovariance(
            pose=pose(xyz, quat_xyzw),
            covariance=float_array(pose_covariance, "pose covariance", COVARIANCE_SIZE),
        ),
        twist=TwistWithCovariance(
            twist=twist(linear_xyz, angular_xyz),
            covariance=float_array(twist_covariance, "twist covariance", COVARIANCE_SIZE),
        ),
    )
