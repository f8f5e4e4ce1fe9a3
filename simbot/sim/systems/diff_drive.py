"""DiffDrive: `cmd_vel` → wheel velocities; wheel encoders → `odom` and the odom → base transform.

SDF parameters (Gazebo's names first; the older names the original robot uses still work):

| parameter | default |
|---|---|
| `left_joint`, `right_joint` (repeatable: every wheel on a side is driven) | required |
| `wheel_separation`, `wheel_radius` | required |
| `topic` | `model/<model>/cmd_vel` |
| `odom_topic` | `model/<model>/odometry` |
| `tf_topic` | `model/<model>/tf` |
| `frame_id` / `odometry_frame` | `<model>/odom` |
| `child_frame_id` / `base_frame` | `<model>/<canonical link>` |
| `odom_publish_frequency` / `update_rate` | 50 Hz |
| `publish_tf` / `broadcast_TF` | true |
| `max_linear_velocity` (`max_velocity`), `min_linear_velocity` | none |
| `max_angular_velocity`, `min_angular_velocity` | none |
| `max_linear_acceleration` (`max_acceleration`), `min_linear_acceleration` | none |
| `max_angular_acceleration`, `min_angular_acceleration` | none |

The defaults are Gazebo Sim's, with `<model>` the model's name in the running world: two
vehicles of one world keep apart keys and tf trees (`vehicle_blue/odom` → `vehicle_blue/chassis`).
The command is limited as every drive's is (simbot.sim.kit.command_pipeline: ramped at the
acceleration limits, then clamped to the velocity limits, each step).

Odometry comes from the wheel encoders only, as on the real robot: when the wheels slip (a skid
turn, a wall) `odom` drifts from the ground truth on `model/<name>/pose`. A skid-steer's wheels
slip in every turn, so odometry over-reports the yaw rate (docs/robot.md, "How the tug turns"):
the twist's covariance says by how much, from the steady turn the model's SDF implies
(`steady_turn.skid_error`): σ_ω = e·|ω| and σ_vy = p·|ω|, with e the yaw rate's over-report and
p the turn centre's offset at the reference turn, over a floor of `TWIST_FLOOR`. A kinematic world
moves the base as commanded: there only the floor. Wheels without the tyre (SDF μ = μ2) keep
dead reckoning's fixed covariance.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

from simbot.bus import messages
from simbot.description.drive_params import DiffDriveParams
from simbot.sim.kit.command_pipeline import Command, CommandPipeline
from simbot.sim.kit.drive import (
    TWIST_COVARIANCE,
    DeadReckoning,
    Drive,
    Encoders,
    OdometryOutput,
    PlanarTwist,
    check_twist,
    joint_effort,
)
from simbot.sim.kit.rates import Paced
from simbot.sim.loop.system import Batch, SystemContext, UpdateInfo
from simbot.sim.physics.kinematic_world import KINEMATIC
from simbot.sim.physics.steady_turn import SkidError, skid_error

TWIST_FLOOR = 1e-6
"""(m/s)² and (rad/s)²: the twist's variance on a straight, where the wheels roll without slip."""
ROLLING_ERROR = 0.01
"""The forward speed's σ per m/s: the wheels roll within 1 % on a straight."""


def twist_covariance(error: SkidError | None, twist: PlanarTwist) -> tuple[float, ...]:
    """The diagonal (x, y, z, roll, pitch, yaw) of odometry's twist covariance at its speed and yaw
    rate; dead reckoning's fixed one where the skid error is unknown (wheels without the tyre)."""
    if error is None:
        return TWIST_COVARIANCE
    speed, _, rate = twist
    return (
        TWIST_FLOOR + (ROLLING_ERROR * speed) ** 2,
        TWIST_FLOOR + (error.side * rate) ** 2,
        *TWIST_COVARIANCE[2:5],
        TWIST_FLOOR + (error.yaw * rate) ** 2,
    )


def wheel_motion(left: float, right: float, radius: float, separation: float) -> tuple[float, float, float]:
    """(forward, lateral, turn) of the base for its sides' mean wheel rotation (rad): a circular arc."""
    dl, dr = left * radius, right * radius
    return (dl + dr) / 2, 0.0, (dr - dl) / separation


def _twist(msg: messages.Twist) -> Command:
    """(v, ω): what a differential drive takes of a twist."""
    return msg.linear.x, msg.angular.z


class DiffDrive(Drive, Paced):
    """Drives both wheels of each side at v ∓ ω·separation/2 over the radius; publishes odometry."""

    name = "DiffDrive"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        self._model, self._name = ctx.require_model("DiffDrive")
        self.params = p = DiffDriveParams.parse(ctx.plugin, self._model, self._name)
        self._physics = ctx.physics
        self._efforts = {j: joint_effort(self._model, j) for j in p.left + p.right}
        commands = ctx.bus.input(p.topic, "geometry_msgs/msg/Twist", check_twist)
        self._pipeline = CommandPipeline(commands, _twist, (p.linear, p.angular))
        self._listen(ctx.bus)
        output = OdometryOutput(
            ctx.bus, p.odom_topic, p.tf_topic if p.publish_tf else None, p.frame_id, p.child_frame_id
        )
        kinematic = ctx.world.physics.type == KINEMATIC
        skid = SkidError() if kinematic else skid_error(self._model, self._physics.step_size)
        encoders = Encoders(ctx.physics, self._name, p.left + p.right)
        self._odometry: DeadReckoning = DeadReckoning(output, encoders, p.odom_rate, partial(twist_covariance, skid))
        self.every = self._odometry.every

    def apply(self, command: Command) -> None:
        v, w = command
        half = w * self.params.separation / 2
        for joints, speed in ((self.params.left, v - half), (self.params.right, v + half)):
            for joint in joints:
                self._physics.set_joint_velocity(self._name, joint, speed / self.params.radius, self._efforts[joint])
        self._physics.drive_base(self._name, v, 0.0, w)

    @classmethod
    def post_update_all(cls, batches: Sequence[Batch]) -> None:
        """Each world's drives due now (the loop hands a paced class no other) sample their
        odometry, one after the other: a fleet's hundreds at 50 Hz in one call of the loop."""
        for drives, info in batches:
            for drive in drives:
                drive.post_update(info)

    def post_update(self, info: UpdateInfo) -> None:
        rotations = self._odometry.due(info.sim_time_ns)
        if rotations is None:
            return
        p, sides = self.params, len(self.params.left)
        left, right = sum(rotations[:sides]) / sides, sum(rotations[sides:]) / len(p.right)
        self._odometry.advance(info.sim_time_ns, *wheel_motion(left, right, p.radius, p.separation))
