"""`robot_description` (the URDF), `tf_static` (its fixed joints and the sensor frames) and `tf` of its movable joints.

What ROS's robot_state_publisher does: every fixed joint of the URDF on `robot_description`
becomes a latched transform, so the two always agree; and every movable joint of the URDF
(revolute, continuous, prismatic: the wheels and each castor's yaw, pitch and roll) a transform
on `tf` at the joint-state rate, from the positions the physics knows. Not only the joints the
SDF's JointStatePublisher names: RViz wants every link reachable from `odom` at all times.
A joint that moves in the URDF but that the physics holds fixed (`Physics.fixed_castors`: the
castors' gimbals) goes on `tf_static` at its zero position, as it never moves: 12 of the tug's 16
transforms, which cost a tenth of a ten-tug server's time at 30 Hz on `tf`.
`robot_description` names meshes by `file://` URIs, which a ROS host on the same machine resolves. A sensor whose frame
is not a link (the cameras) adds its link → frame transform at the sensor's SDF pose; a sensor
whose frame is its link (the lidars) already has it, as the URDF puts that link's frame at the
sensor. Each camera also gets its optical frame (z forward, x right, y down), which its images
are stamped in.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.bus import messages
from simbot.bus.frames import OPTICAL_RPY, optical_frame
from simbot.description.kinematics import KinematicTree, UrdfJoint
from simbot.description.model import Model
from simbot.description.naming import sensor_frame
from simbot.description.poses import Pose
from simbot.description.urdf_writer import link_frame, model_to_urdf
from simbot.sim.kit.joints import JOINT_STATE_RATE_HZ, MOVABLE
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.registry import SENSOR_GROUP, registered
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.sim.physics import compose, pose_to_transform
from simbot.transform import Transform, Vec3, axis_quaternion


@dataclass(frozen=True)
class MovableJoint:
    """A URDF joint that moves: its links, its origin in the parent and its axis."""

    name: str
    parent: str
    child: str
    origin: Transform
    axis: Vec3
    prismatic: bool

    @staticmethod
    def of(joint: UrdfJoint) -> MovableJoint:
        origin = pose_to_transform(joint.origin)
        return MovableJoint(joint.name, joint.parent, joint.child, origin, joint.axis, joint.type == "prismatic")

    def transform(self, position: float) -> Transform:
        """The child's frame in the parent's at `position` (rad or m): the origin, then the motion along the axis."""
        if self.prismatic:
            x, y, z = self.axis
            return compose(self.origin, Transform((x * position, y * position, z * position)))
        return compose(self.origin, Transform((0.0, 0.0, 0.0), axis_quaternion(self.axis, position)))


def movable_joints(tree: KinematicTree) -> list[MovableJoint]:
    """The URDF's revolute, continuous and prismatic joints, in document order."""
    return [MovableJoint.of(joint) for joint in tree.joints if joint.type in MOVABLE]


def static_transforms(model: Model, tree: KinematicTree) -> list[tuple[str, str, Pose]]:
    """(parent, child, child pose in parent) for the URDF's fixed joints and the non-link sensor frames."""
    found = [(joint.parent, joint.child, joint.origin) for joint in tree.joints if joint.fixed]
    for link, sensor in model.sensors():
        frame = sensor_frame(sensor)
        if frame not in tree.links:
            found.append((link.name, frame, link_frame(link).inverse() @ link.pose @ sensor.pose))
        if getattr(registered(SENSOR_GROUP).get(sensor.type), "in_optical_frame", False):
            found.append((frame, optical_frame(frame), Pose(rpy=OPTICAL_RPY)))
    return found


class RobotStatePublisher(Paced):
    """Built into the server for the robot: the description and static tree once, latched; the movable joints at their rate."""

    name = "RobotStatePublisher"

    def __init__(self, ctx: SystemContext) -> None:
        model, self._name = ctx.require_model("RobotStatePublisher")
        tree, held = ctx.physics.kinematics(self._name), ctx.physics.held_joints(self._name)
        ctx.bus.publisher("robot_description", messages.String, latched=True).put(
            messages.string(model_to_urdf(model, mesh_uris=True))
        )
        joints = movable_joints(tree)
        transforms = [
            messages.transform_stamped(0, parent, child, *pose_to_transform(pose))
            for parent, child, pose in static_transforms(model, tree)
        ] + [
            messages.transform_stamped(0, joint.parent, joint.child, *joint.transform(0.0))
            for joint in joints
            if joint.name in held
        ]
        ctx.bus.publisher("tf_static", messages.TFMessage, latched=True).put(messages.tf_message(transforms))
        self._physics = ctx.physics
        self._joints = [joint for joint in joints if joint.name not in held]
        self._frames = [(ctx.bus.frame(joint.parent), ctx.bus.frame(joint.child)) for joint in self._joints]
        """Each moving joint's (parent, child) frames as published: prefixed once, not copied per message."""
        self._tf = ctx.bus.publisher("tf", messages.TFMessage) if self._joints else None
        self.every = Every.hz(JOINT_STATE_RATE_HZ)

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if self._tf is None or not self.every.due(now_ns) or not self._tf.has_subscribers:
            return
        states = self._physics.joint_states(self._name, [joint.name for joint in self._joints])
        transforms = [
            messages.transform_stamped(now_ns, parent, child, *joint.transform(state[0]))
            for joint, (parent, child), state in zip(self._joints, self._frames, states)
        ]
        self._tf.put(messages.tf_message(transforms))

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
