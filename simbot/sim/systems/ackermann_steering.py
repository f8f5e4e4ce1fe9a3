"""AckermannSteering: a car's twist → steering angles and wheel speeds; odometry from them (Gazebo's AckermannSteering).

| parameter | default |
|---|---|
| `left_joint`, `right_joint` (repeatable: the driven wheels of each side) | required |
| `left_steering_joint`, `right_steering_joint` | required |
| `wheel_separation` (m, between the left and right wheels) | 1.0 |
| `kingpin_width` (m, between the steering axes) | 0.8 |
| `wheel_base` (m, front to rear axle) | 1.0 |
| `wheel_radius` (m) | 0.2 |
| `steering_limit` (rad) | 0.5 |
| `steer_p_gain` (1/s: steering joint speed per radian of error) | 1.0 |
| `steering_only` | false |
| `topic` | `model/<model>/cmd_vel`; `model/<model>/steer_angle` when steering only |
| `sub_topic` | none; else the input is `model/<model>/<sub_topic>` |
| `odom_topic`, `tf_topic` | `model/<model>/odometry`, `model/<model>/tf` |
| `frame_id`, `child_frame_id` | `<model>/odom`, `<model>/<canonical link>` |
| `odom_publish_frequency` | 50 Hz |
| `min_velocity`, `max_velocity`, `min_acceleration`, `max_acceleration` | none (bound both v and ω, as in Gazebo) |

Input: geometry_msgs/Twist (v = linear.x, ω = angular.z), or with `steering_only` a
std_msgs/Float64 steering angle. The turning radius of the rear axle's centre is R = v/ω,
no tighter than wheel_base / sin(steering_limit) (Gazebo's bound); the steering joints turn
toward the Ackermann angles atan(L / (R ∓ kingpin_width/2)) at `steer_p_gain` × error, and each
side's wheels run at v (1 ∓ wheel_separation / 2R) / wheel_radius. A turn commanded at v = 0
steers full lock and stands. Odometry integrates the first left and right wheels' rotation
along the arc their steering angles give (the car's bicycle angle φ: cot φ = mean of the two
cotangents), from the start pose, so it drifts where the wheels slip. Gazebo's `min_jerk`,
`max_jerk` are ignored with a warning; `use_actuator_msg` is refused. The command (the twist, or
the steering angle) is limited as every drive's is (simbot.sim.kit.command_pipeline); the
steering servo follows its angles every step, as Gazebo's PID does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from simbot.bus import messages
from simbot.description.drive_params import Limits, limits
from simbot.description.model import Model, Plugin
from simbot.description.plugin_params import bool_param
from simbot.sim.kit.command_pipeline import Command, CommandPipeline
from simbot.sim.kit.drive import (
    DeadReckoning,
    Drive,
    Encoders,
    OdometryOutput,
    check_float,
    check_twist,
    command_topic,
    joint_effort,
    positive,
    refuse_actuators,
    require_joints,
    warn_unsupported,
)
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo

STRAIGHT = 0.001
"""rad/s of commanded turn below which the car drives straight (Gazebo's threshold)."""


@dataclass(frozen=True)
class AckermannParams:
    left: tuple[str, ...]
    right: tuple[str, ...]
    left_steering: str
    right_steering: str
    separation: float
    kingpin_width: float
    wheel_base: float
    radius: float
    steering_limit: float
    steer_gain: float
    steering_only: bool
    odom_rate: float
    limits: Limits

    @staticmethod
    def parse(plugin: Plugin, model: Model) -> AckermannParams:
        warn_unsupported(plugin, "min_jerk", "max_jerk")
        steering = [require_joints(plugin, model, tag) for tag in ("left_steering_joint", "right_steering_joint")]
        if any(len(joints) > 1 for joints in steering):
            raise SystemConfigError(f"{plugin.name}: one <left_steering_joint> and one <right_steering_joint>")
        limit = positive(plugin, "steering_limit", 0.5)
        if limit >= math.pi / 2:
            raise SystemConfigError(f"{plugin.name}: <steering_limit> must be below π/2, got {limit:g}")
        return AckermannParams(
            require_joints(plugin, model, "left_joint"), require_joints(plugin, model, "right_joint"),
            steering[0][0], steering[1][0],
            positive(plugin, "wheel_separation", 1.0), positive(plugin, "kingpin_width", 0.8),
            positive(plugin, "wheel_base", 1.0), positive(plugin, "wheel_radius", 0.2), limit,
            positive(plugin, "steer_p_gain", 1.0), bool_param(plugin, "steering_only", default=False),
            positive(plugin, "odom_publish_frequency", 50.0), limits(plugin, None),
        )  # fmt: skip

    def curvature(self, v: float, w: float) -> float:
        """1/R of the rear axle's centre for a twist, within the steering limit (0: straight)."""
        if abs(w) < STRAIGHT:
            return 0.0
        tightest = math.sin(self.steering_limit) / self.wheel_base
        if v == 0.0:
            return math.copysign(tightest, w)
        return max(-tightest, min(tightest, w / v))

    def steering_angles(self, curvature: float, width: float) -> tuple[float, float]:
        """(left, right) angles that turn wheels `width` apart about one centre at 1/curvature."""
        k = curvature
        return (
            math.atan(self.wheel_base * k / (1.0 - k * width / 2)),
            math.atan(self.wheel_base * k / (1.0 + k * width / 2)),
        )


def bicycle_curvature(left: float, right: float, wheel_base: float) -> float:
    """The rear axle centre's 1/R that two steering angles give: tan φ / L with cot φ their mean cotangent."""
    tl, tr = math.tan(left), math.tan(right)
    return 0.0 if abs(tl + tr) < 1e-12 else 2.0 * tl * tr / (tl + tr) / wheel_base


def _twist(msg: messages.Twist) -> Command:
    """(v, ω): what a car takes of a twist."""
    return msg.linear.x, msg.angular.z


def _angle(msg: messages.Float64) -> Command:
    """The bicycle angle, steering only."""
    return (msg.data,)


class AckermannSteering(Drive):
    """Steers and drives a car; publishes its odometry."""

    name = "AckermannSteering"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._name = ctx.require_model("AckermannSteering")
        refuse_actuators(ctx.plugin)
        self.params = p = AckermannParams.parse(ctx.plugin, model)
        self._physics = ctx.physics
        self._efforts = {j: joint_effort(model, j) for j in (*p.left, *p.right, p.left_steering, p.right_steering)}
        self._odometry: DeadReckoning | None = None
        if p.steering_only:
            topic = command_topic(ctx, ctx.plugin, "steer_angle")
            angles = ctx.bus.input(topic, "std_msgs/msg/Float64", check_float)
            self._pipeline = CommandPipeline(angles, _angle, (p.limits,))
        else:
            topic = command_topic(ctx, ctx.plugin, "cmd_vel")
            twists = ctx.bus.input(topic, "geometry_msgs/msg/Twist", check_twist)
            self._pipeline = CommandPipeline(twists, _twist, (p.limits, p.limits))
            self._odometry = DeadReckoning(
                OdometryOutput.from_plugin(ctx, ctx.plugin, model, self._name),
                Encoders(ctx.physics, self._name, (p.left[0], p.right[0])),
                p.odom_rate,
            )
        self._listen(ctx.bus)
        self._steering = (0.0, 0.0)
        """The (left, right) angles the steering servo turns the wheels to."""

    @property
    def idle(self) -> bool:
        """Never: the steering servo is driven at every step."""
        return False

    def pre_update(self, info: UpdateInfo) -> None:
        super().pre_update(info)
        self._steer()

    def apply(self, command: Command) -> None:
        if self.params.steering_only:
            self._steering = self._angles_for(command[0])
        else:
            self._drive(*command)

    def _angles_for(self, angle: float) -> tuple[float, float]:
        """Steering only: the bicycle angle, bounded by the limit, spread over the wheels `wheel_separation` apart."""
        p = self.params
        angle = max(-p.steering_limit, min(p.steering_limit, angle))
        return p.steering_angles(math.tan(angle) / p.wheel_base, p.separation)

    def _drive(self, v: float, w: float) -> None:
        p = self.params
        k = p.curvature(v, w)
        self._steering = p.steering_angles(k, p.kingpin_width)
        self._physics.drive_base(self._name, v, 0.0, v * k)
        for joints, speed in ((p.left, v * (1 - k * p.separation / 2)), (p.right, v * (1 + k * p.separation / 2))):
            for joint in joints:
                self._physics.set_joint_velocity(self._name, joint, speed / p.radius, self._efforts[joint])

    def _steer(self) -> None:
        """The steering joints' speeds toward their angles: a P servo, so every step."""
        p = self.params
        now = self._physics.joint_states(self._name, [p.left_steering, p.right_steering])
        for joint, target, state in zip((p.left_steering, p.right_steering), self._steering, now):
            self._physics.set_joint_velocity(
                self._name, joint, p.steer_gain * (target - state[0]), self._efforts[joint]
            )

    def post_update(self, info: UpdateInfo) -> None:
        rotations = self._odometry.due(info.sim_time_ns) if self._odometry is not None else None
        if self._odometry is None or rotations is None:
            return
        p = self.params
        distance = (rotations[0] + rotations[1]) / 2 * p.radius
        steering = self._physics.joint_states(self._name, [p.left_steering, p.right_steering])
        turn = distance * bicycle_curvature(steering[0][0], steering[1][0], p.wheel_base)
        self._odometry.advance(info.sim_time_ns, distance, 0.0, turn)
