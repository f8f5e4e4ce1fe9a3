"""MecanumDrive: a twist with sideways motion → four mecanum wheels; odometry from them (Gazebo's MecanumDrive).

| parameter | default |
|---|---|
| `front_left_joint`, `front_right_joint`, `back_left_joint`, `back_right_joint` (each repeatable) | required |
| `wheelbase` (m, front to back) | 1.0 |
| `wheel_separation` (m, left to right) | 1.0 |
| `wheel_radius` (m) | 0.2 |
| `topic` | `model/<model>/cmd_vel` |
| `odom_topic`, `tf_topic` | `model/<model>/odometry`, `model/<model>/tf` |
| `frame_id`, `child_frame_id` | `<model>/odom`, `<model>/<canonical link>` |
| `odom_publish_frequency` | 50 Hz |
| `min_velocity`, `max_velocity`, `min_acceleration`, `max_acceleration` | none (bound vx, vy and ω alike) |

Input: geometry_msgs/Twist (linear.x, linear.y, angular.z). With l = (wheelbase +
wheel_separation)/2, the wheels turn at (vx ∓ vy ∓ ω·l)/r: front left −,−; front right +,+; back
left +,−; back right −,+. Odometry inverts the same kinematics from the first wheel of each corner.
The command is limited as every drive's is (simbot.sim.kit.command_pipeline).

The rollers: a mecanum wheel only pushes along its rollers' axis, which is what moves the car
sideways. PyBullet has no rollers; as in Gazebo's mecanum example, each wheel's collision
states friction μ along `fdir1` at 45° to the wheel's rolling direction and μ2 = 0 across it,
and simbot's wheel friction applies exactly that (see wheel_friction). What is lost: the
rollers' own inertia and the bump of their discrete contacts.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.bus import messages
from simbot.description.drive_params import Limits, limits
from simbot.description.model import Model, Plugin
from simbot.sim.kit.command_pipeline import Command, CommandPipeline
from simbot.sim.kit.drive import (
    DeadReckoning,
    Drive,
    Encoders,
    OdometryOutput,
    check_twist,
    command_topic,
    joint_effort,
    positive,
    require_joints,
    warn_unsupported,
)
from simbot.sim.kit.rates import Paced
from simbot.sim.loop.system import SystemContext, UpdateInfo

CORNERS = ("front_left", "front_right", "back_left", "back_right")
SIGNS = ((-1.0, -1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, 1.0))
"""(sideways, turning) sign of each corner's wheel speed, in CORNERS order."""


@dataclass(frozen=True)
class MecanumParams:
    wheels: tuple[tuple[str, ...], ...]
    """The joints of each corner, in CORNERS order."""
    wheelbase: float
    separation: float
    radius: float
    odom_rate: float
    limits: Limits

    @staticmethod
    def parse(plugin: Plugin, model: Model) -> MecanumParams:
        warn_unsupported(plugin, "min_jerk", "max_jerk")
        return MecanumParams(
            tuple(require_joints(plugin, model, f"{corner}_joint") for corner in CORNERS),
            positive(plugin, "wheelbase", 1.0),
            positive(plugin, "wheel_separation", 1.0),
            positive(plugin, "wheel_radius", 0.2),
            positive(plugin, "odom_publish_frequency", 50.0),
            limits(plugin, None),
        )

    @property
    def lever(self) -> float:
        return (self.wheelbase + self.separation) / 2

    def wheel_speeds(self, vx: float, vy: float, w: float) -> list[float]:
        """rad/s of each corner for a twist."""
        return [(vx + side * vy + turn * w * self.lever) / self.radius for side, turn in SIGNS]

    def twist(self, rotations: list[float]) -> tuple[float, float, float]:
        """(forward, sideways, turn) that the corners' rotations give: the inverse of `wheel_speeds`."""
        r = self.radius / 4
        return (
            r * sum(rotations),
            r * sum(side * a for (side, _), a in zip(SIGNS, rotations)),
            r * sum(turn * a for (_, turn), a in zip(SIGNS, rotations)) / self.lever,
        )


def _twist(msg: messages.Twist) -> Command:
    """(vx, vy, ω): what a mecanum platform takes of a twist."""
    return msg.linear.x, msg.linear.y, msg.angular.z


class MecanumDrive(Drive, Paced):
    """Drives four mecanum wheels; publishes odometry."""

    name = "MecanumDrive"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._name = ctx.require_model("MecanumDrive")
        self.params = p = MecanumParams.parse(ctx.plugin, model)
        self._physics = ctx.physics
        self._efforts = {j: joint_effort(model, j) for corner in p.wheels for j in corner}
        commands = ctx.bus.input(command_topic(ctx, ctx.plugin, "cmd_vel"), "geometry_msgs/msg/Twist", check_twist)
        self._pipeline = CommandPipeline(commands, _twist, (p.limits,) * 3)
        self._listen(ctx.bus)
        self._odometry: DeadReckoning = DeadReckoning(
            OdometryOutput.from_plugin(ctx, ctx.plugin, model, self._name),
            Encoders(ctx.physics, self._name, tuple(corner[0] for corner in p.wheels)),
            p.odom_rate,
        )
        self.every = self._odometry.every

    def apply(self, command: Command) -> None:
        vx, vy, w = command
        self._physics.drive_base(self._name, vx, vy, w)
        for corner, speed in zip(self.params.wheels, self.params.wheel_speeds(vx, vy, w)):
            for joint in corner:
                self._physics.set_joint_velocity(self._name, joint, speed, self._efforts[joint])

    def post_update(self, info: UpdateInfo) -> None:
        rotations = self._odometry.due(info.sim_time_ns)
        if rotations is not None:
            self._odometry.advance(info.sim_time_ns, *self.params.twist(rotations))
