"""geometry_msgs and tf2_msgs: vectors, poses, twists, wrenches and the transforms of tf."""

from __future__ import annotations

from collections.abc import Iterable

from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import (
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Twist,
    Vector3,
    Wrench,
    WrenchStamped,
)
from simbot.bus.messages.values import Floats, floats, three


def vector3(x: float, y: float, z: float) -> Vector3:
    """geometry_msgs/Vector3."""
    return Vector3(x=float(x), y=float(y), z=float(z))


def quaternion(x: float, y: float, z: float, w: float) -> Quaternion:
    """geometry_msgs/Quaternion, in ROS order x, y, z, w."""
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def quaternion_of(quat_xyzw: Floats) -> Quaternion:
    """geometry_msgs/Quaternion of four values x, y, z, w (ValueError for any other count)."""
    return quaternion(*floats(quat_xyzw, 4, "quaternion (x, y, z, w)"))


def transform_stamped(ns: int, parent: str, child: str, xyz: Floats, quat_xyzw: Floats) -> TransformStamped:
    """geometry_msgs/TransformStamped: the pose of `child` in `parent`."""
    translation = vector3(*three(xyz, "translation"))
    return TransformStamped(
        header=header(ns, parent),
        child_frame_id=child,
        transform=Transform(translation=translation, rotation=quaternion_of(quat_xyzw)),
    )


def tf_message(transforms: Iterable[TransformStamped]) -> TFMessage:
    """tf2_msgs/TFMessage holding `transforms`."""
    return TFMessage(transforms=list(transforms))


def twist(linear_xyz: Floats = (0.0, 0.0, 0.0), angular_xyz: Floats = (0.0, 0.0, 0.0)) -> Twist:
    """geometry_msgs/Twist; no arguments is a stop."""
    return Twist(linear=vector3(*three(linear_xyz, "linear")), angular=vector3(*three(angular_xyz, "angular")))


def pose(xyz: Floats, quat_xyzw: Floats) -> Pose:
    """geometry_msgs/Pose at `xyz` turned by `quat_xyzw`."""
    x, y, z = three(xyz, "position")
    return Pose(position=Point(x=x, y=y, z=z), orientation=quaternion_of(quat_xyzw))


def pose_stamped(ns: int, frame: str, xyz: Floats, quat_xyzw: Floats) -> PoseStamped:
    """geometry_msgs/PoseStamped in `frame`."""
    return PoseStamped(header=header(ns, frame), pose=pose(xyz, quat_xyzw))


def wrench(force_xyz: Floats, torque_xyz: Floats) -> Wrench:
    """geometry_msgs/Wrench: newtons and newton-metres."""
    return Wrench(force=vector3(*three(force_xyz, "force")), torque=vector3(*three(torque_xyz, "torque")))


def wrench_stamped(ns: int, frame: str, force_xyz: Floats, torque_xyz: Floats) -> WrenchStamped:
    """geometry_msgs/WrenchStamped: newtons and newton-metres."""
    return WrenchStamped(header=header(ns, frame), wrench=wrench(force_xyz, torque_xyz))
