"""What the drive and joint systems share (DiffDrive, AckermannSteering, MecanumDrive,
VelocityControl, OdometryPublisher, the joint controllers): command checks, parameters, wheel
encoders, planar dead reckoning and the odometry/tf output with Gazebo's defaults. Their velocity
limits, which the gym reads too, are simbot.description.drive_params.

One owner for each piece, so that a fix to the limits or the odometry message reaches every drive.
"""

from __future__ import annotations

import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from simbot.bus import Publisher, messages
from simbot.description.model import Model, Plugin
from simbot.description.naming import scoped_key
from simbot.description.plugin_params import bool_param, number_param, param
from simbot.sim.kit.command_pipeline import Command, CommandPipeline
from simbot.sim.kit.rates import Every
from simbot.sim.loop.bus_view import Doorbell, SimBus
from simbot.sim.loop.system import Batch, SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.physics import WorldReader
from simbot.transform import yaw_quaternion

log = logging.getLogger(__name__)

ABSURD_SPEED = 100.0
"""m/s or rad/s beyond which a command is malformed, not merely fast: it is dropped, not clamped."""
POSE_COVARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
TWIST_COVARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
"""Diagonals (x, y, z, roll, pitch, yaw): planar odometry knows nothing of z, roll and pitch."""
Vec3 = tuple[float, float, float]
UNLIMITED_EFFORT = 1e16
"""N·m or N for a joint whose SDF states no effort limit: Gazebo's velocity command is exact there."""


def positive(plugin: Plugin, tag: str, default: float) -> float:
    """A positive number parameter, `default` where the SDF gives none."""
    value = number_param(plugin, tag, default=default, positive=True)
    assert value is not None
    return value


def warn_unsupported(plugin: Plugin, *tags: str) -> None:
    """Gazebo parameters simbot does not implement and can do without (jerk limits): a warning each."""
    for tag in tags:
        if plugin.get(tag) is not None:
            log.warning("%s: <%s> is not supported; ignored", plugin.name, tag)


def refuse_actuators(plugin: Plugin) -> None:
    """Gazebo's `use_actuator_msg` takes gz.msgs.Actuators, which has no ROS 2 counterpart."""
    if bool_param(plugin, "use_actuator_msg", default=False):
        raise SystemConfigError(
            f"{plugin.name}: <use_actuator_msg> is not supported (gz.msgs.Actuators is no ROS 2 message)"
        )


def check_twist(msg: Any) -> str | None:
    """Why a Twist is no command: NaN, infinite or absurd components."""
    values = (msg.linear.x, msg.linear.y, msg.linear.z, msg.angular.x, msg.angular.y, msg.angular.z)
    if not all(math.isfinite(v) for v in values):
        return f"non-finite velocity {values}"
    if max(abs(v) for v in values) > ABSURD_SPEED:
        return f"absurd velocity: linear {values[:3]}, angular {values[3:]} (limit {ABSURD_SPEED})"
    return None


def check_float(msg: Any) -> str | None:
    """Why a Float64 is no joint command: NaN or infinite."""
    return None if math.isfinite(msg.data) else f"non-finite value {msg.data}"


def joint_effort(model: Model, joint: str) -> float:
    """The joint's SDF effort limit: the most a velocity servo on it may exert."""
    axis = model.joint(joint).axis
    return axis.effort if axis is not None and axis.effort is not None else UNLIMITED_EFFORT


def require_joints(plugin: Plugin, model: Model, tag: str) -> tuple[str, ...]:
    """Every `<tag>` of the plugin (at least one), each a joint of the model."""
    joints = tuple(plugin.get_all(tag))
    if not joints:
        raise SystemConfigError(f"{plugin.name}: needs at least one <{tag}>")
    known = {j.name for j in model.joints}
    for joint in joints:
        if joint not in known:
            raise SystemConfigError(f"{plugin.name}: <{tag}> {joint!r}: model {model.name!r} has no such joint")
    return joints


def command_topic(ctx: SystemContext, plugin: Plugin, default_leaf: str) -> str:
    """`<topic>`, else `model/<m>/<sub_topic>`, else `model/<m>/<default_leaf>`: Gazebo's order."""
    sub_topic = param(plugin, "sub_topic")
    return param(plugin, "topic") or ctx.model_topic(sub_topic.strip("/") if sub_topic else default_leaf)


def vector_param(plugin: Plugin, tag: str, default: Vec3 = (0.0, 0.0, 0.0)) -> Vec3:
    """Three numbers (`<initial_linear>0.5 0 0</initial_linear>`); anything else is an error naming the tag."""
    text = param(plugin, tag)
    if text is None:
        return default
    try:
        x, y, z = (float(part) for part in text.split())
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{tag}> expected three numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise SystemConfigError(f"{plugin.name}: <{tag}> must be finite, got {text!r}")
    return x, y, z


class Encoders:
    """Wheel joints' rotation since the last reading: what dead reckoning integrates."""

    def __init__(self, physics: WorldReader, model: str, joints: tuple[str, ...]) -> None:
        self._physics, self._model, self._joints = physics, model, list(joints)
        self._last = self._read()

    def deltas(self) -> list[float]:
        """Radians (or metres) each joint moved since the last call (or since the encoders were
        made or restarted: the first step's turn counts, as a real encoder's would)."""
        now = self._read()
        last, self._last = self._last, now
        return [a - b for a, b in zip(now, last)]

    def restart(self) -> None:
        """Counting from where the joints stand now (a reset put them back)."""
        self._last = self._read()

    def _read(self) -> list[float]:
        return [state[0] for state in self._physics.joint_states(self._model, self._joints)]


@dataclass
class PlanarPose:
    """A pose in the plane, advanced by motions given in its own frame along exact arcs."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def advance(self, forward: float, lateral: float, turn: float) -> None:
        """Moves by (forward, lateral) metres of its own frame while turning `turn` radians: the
        constant-twist path (an arc), exact for any step, so odometry does not drift with the rate."""
        if abs(turn) > 1e-9:
            s, c = math.sin(turn) / turn, (1.0 - math.cos(turn)) / turn
            forward, lateral = forward * s - lateral * c, forward * c + lateral * s
        cos_yaw, sin_yaw = math.cos(self.yaw), math.sin(self.yaw)
        self.x += forward * cos_yaw - lateral * sin_yaw
        self.y += forward * sin_yaw + lateral * cos_yaw
        end = self.yaw + turn
        self.yaw = math.atan2(math.sin(end), math.cos(end))

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        return yaw_quaternion(self.yaw)


class OdometryOutput:
    """nav_msgs/Odometry on one key and, optionally, the same frame → child transform on a tf key."""

    @staticmethod
    def from_plugin(ctx: SystemContext, plugin: Plugin, model: Model, name: str) -> OdometryOutput:
        """`odom_topic`, `tf_topic`, `frame_id`, `child_frame_id` with Gazebo's defaults:
        `model/<m>/odometry`, `model/<m>/tf`, `<m>/odom`, `<m>/<canonical link>`."""
        frame = scoped_key(name)
        return OdometryOutput(
            ctx.bus,
            param(plugin, "odom_topic") or ctx.model_topic("odometry"),
            param(plugin, "tf_topic") or ctx.model_topic("tf"),
            param(plugin, "frame_id") or f"{frame}/odom",
            param(plugin, "child_frame_id") or f"{frame}/{model.canonical_link}",
        )

    def __init__(self, bus: SimBus, odom_topic: str, tf_topic: str | None, frame_id: str, child_frame_id: str) -> None:
        self._odom = bus.publisher(odom_topic, messages.Odometry)
        self._tf = bus.publisher(tf_topic, messages.TFMessage) if tf_topic is not None else None
        self.frame_id, self.child_frame_id = bus.frame(frame_id), bus.frame(child_frame_id)

    @property
    def watched(self) -> bool:
        """Whether anyone subscribes to the odometry or its transform."""
        return self._odom.has_subscribers or (self._tf is not None and self._tf.has_subscribers)

    def put_planar(
        self,
        now_ns: int,
        pose: PlanarPose,
        linear: tuple[float, float],
        turn_rate: float,
        twist_covariance: tuple[float, ...],
    ) -> None:
        """Planar odometry with the pose covariance of dead reckoning (z, roll and pitch unknown) and
        the twist's diagonal the drive states (its caller asks `watched` first: a fleet's covariances
        are built for the robots someone reads)."""
        self.put(
            now_ns,
            ((pose.x, pose.y, 0.0), pose.quaternion),
            ((linear[0], linear[1], 0.0), (0.0, 0.0, turn_rate)),
            diagonal(POSE_COVARIANCE),
            diagonal(twist_covariance),
        )

    def put(
        self,
        now_ns: int,
        pose: tuple[tuple[float, float, float], tuple[float, float, float, float]],
        twist: tuple[tuple[float, float, float], tuple[float, float, float]],
        pose_covariance: list[float],
        twist_covariance: list[float],
        also: Publisher | None = None,
    ) -> None:
        """The pose in `frame_id` and the twist in `child_frame_id`, stamped `now_ns`, also on `also`
        (a second key of the same message). Built only for a key someone subscribes to: a fleet's
        odometry is read for a few robots."""
        xyz, quat = pose
        keys = [key for key in (self._odom, also) if key is not None and key.has_subscribers]
        if keys:
            odometry = messages.odometry(
                now_ns, self.frame_id, self.child_frame_id, xyz, quat, *twist, pose_covariance, twist_covariance
            )
            for key in keys:
                key.put(odometry)
        if self._tf is not None and self._tf.has_subscribers:
            transform = messages.transform_stamped(now_ns, self.frame_id, self.child_frame_id, xyz, quat)
            self._tf.put(messages.tf_message([transform]))


def diagonal(values: tuple[float, ...]) -> list[float]:
    """A row-major 6×6 covariance with `values` on its diagonal."""
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[i * 7] = value
    return matrix


PlanarTwist = tuple[float, float, float]
"""(forward m/s, lateral m/s, turn rad/s) in the robot's own frame."""
TwistCovariance = Callable[[PlanarTwist], tuple[float, ...]]
"""The diagonal of odometry's twist covariance at a twist: a drive that knows how its wheels err states it."""


def fixed_twist_covariance(twist: PlanarTwist) -> tuple[float, ...]:
    """Dead reckoning's covariance whatever the twist: what a drive knows nothing better of."""
    return TWIST_COVARIANCE


class DeadReckoning:
    """Wheel-encoder odometry at its own rate (`every`): integrates each motion, publishes pose and mean twist.

    The drive turns its encoders' rotations into a motion of its own frame (its kinematics); this
    integrates it along the exact arc and publishes, so every drive's odometry is one piece of code."""

    def __init__(
        self,
        output: OdometryOutput,
        encoders: Encoders,
        rate_hz: float,
        covariance: TwistCovariance = fixed_twist_covariance,
    ) -> None:
        self._output, self._encoders, self._covariance = output, encoders, covariance
        self.frames = (output.frame_id, output.child_frame_id)
        """(odometry frame, child frame) as published: the robot's namespace prefixed."""
        self.every = Every.hz(rate_hz)
        self.pose = PlanarPose()
        self._last_ns = 0

    def due(self, now_ns: int) -> list[float] | None:
        """The encoders' rotation since the last update when one is due, else None."""
        return self._encoders.deltas() if self.every.due(now_ns) else None

    def advance(self, now_ns: int, forward: float, lateral: float, turn: float) -> None:
        """Moves by a motion of the robot's own frame and publishes; the twist is its mean since the last."""
        self.pose.advance(forward, lateral, turn)
        dt = (now_ns - self._last_ns) / 1e9
        self._last_ns = now_ns
        if self._output.watched:  # a fleet's odometry is read for a few robots
            twist = (forward / dt, lateral / dt, turn / dt) if dt > 0 else (0.0, 0.0, 0.0)
            self._output.put_planar(now_ns, self.pose, twist[:2], twist[2], self._covariance(twist))

    def restart(self, now_ns: int) -> None:
        """From the origin again, the encoders counting from where the wheels stand."""
        self.pose = PlanarPose()
        self._encoders.restart()
        self.every.restart()
        self._last_ns = now_ns


class Drive(ABC):
    """What every drive system is around its own kinematics (`apply`): before each step the command
    its pipeline limited, when there is one to apply; at a reset the pipeline at zero and the
    odometry from the origin; the frames its odometry publishes."""

    _pipeline: CommandPipeline
    _odometry: DeadReckoning | None

    @abstractmethod
    def apply(self, command: Command) -> None:
        """The wheels' speeds and the base's twist (`drive_base`) for a limited command."""

    @property
    def odometry_frames(self) -> tuple[str, str] | None:
        """(odometry frame, child frame) as it publishes them (prefixed with the robot's namespace); None: no odometry."""
        return None if self._odometry is None else self._odometry.frames

    _bell: Doorbell

    def _listen(self, bus: SimBus) -> None:
        """Its commands ring the world's doorbell of its kind (`pre_update_all` steps it then); call
        once its pipeline is made."""
        self._bell = bus.doorbell(type(self).__name__)
        self._pipeline.rings(self._bell, self)

    def pre_update(self, info: UpdateInfo) -> None:
        command = self._pipeline.step(info.step_ns / 1e9)
        if command is not None:
            self.apply(command)

    @property
    def idle(self) -> bool:
        """Whether this step's `pre_update` would do nothing: its command holds and no message
        waits. A drive with work of its own at every step (a steering servo) says False."""
        return self._pipeline.idle

    @classmethod
    def pre_update_all(cls, batches: Sequence[Batch]) -> None:
        """Every drive of each world that has something to do: those whose commands rang its
        doorbell, and those still ramping, which ring it again themselves; an idle one (most of a
        fleet, most steps) costs nothing."""
        for drives, info in batches:
            bell = drives[0]._bell
            for drive in bell.answer():
                drive.pre_update(info)
                if not drive.idle:
                    bell.ring(drive)

    def reset(self, info: UpdateInfo) -> None:
        self._pipeline.reset()
        self._bell.ring(self)  # the limited zero, at the next step
        if self._odometry is not None:
            self._odometry.restart(info.sim_time_ns)
