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

from dataclasses import dataclass, field

from simbot.description.drive_params import DiffDriveParams
from simbot.sim.kit.drive import TWIST_COVARIANCE, OdometryOutput, PlanarPose, check_twist, joint_effort
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.sim.physics.kinematic_stepper import KINEMATIC
from simbot.sim.physics.steady_turn import SkidError, skid_error


@dataclass
class Odometry:
    """Dead reckoning from the mean encoder angle of each side: each update is an exact circular arc."""

    pose: PlanarPose = field(default_factory=PlanarPose)
    left: float | None = None
    right: float | None = None

    def update(self, left: float, right: float, radius: float, separation: float) -> tuple[float, float]:
        """Advances by the wheel rotation since the last call; returns the distance and turn."""
        if self.left is None or self.right is None:
            self.left, self.right = left, right
            return 0.0, 0.0
        dl, dr = (left - self.left) * radius, (right - self.right) * radius
        self.left, self.right = left, right
        distance, turn = (dl + dr) / 2, (dr - dl) / separation
        self.pose.advance(distance, 0.0, turn)
        return distance, turn


TWIST_FLOOR = 1e-6
"""(m/s)² and (rad/s)²: the twist's variance on a straight, where the wheels roll without slip."""
ROLLING_ERROR = 0.01
"""The forward speed's σ per m/s: the wheels roll within 1 % on a straight."""


def twist_covariance(error: SkidError | None, speed: float, rate: float) -> tuple[float, ...]:
    """The diagonal (x, y, z, roll, pitch, yaw) of odometry's twist covariance at its speed and yaw
    rate; dead reckoning's fixed one where the skid error is unknown (wheels without the tyre)."""
    if error is None:
        return TWIST_COVARIANCE
    return (
        TWIST_FLOOR + (ROLLING_ERROR * speed) ** 2,
        TWIST_FLOOR + (error.side * rate) ** 2,
        *TWIST_COVARIANCE[2:5],
        TWIST_FLOOR + (error.yaw * rate) ** 2,
    )


class DiffDrive(Paced):
    """Drives both wheels of each side at v ∓ ω·separation/2 over the radius; publishes odometry."""

    name = "DiffDrive"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        self._model, self._name = ctx.require_model("DiffDrive")
        self.params = DiffDriveParams.parse(ctx.plugin, self._model, self._name)
        self._physics = ctx.physics
        self._efforts = {j: joint_effort(self._model, j) for j in self.params.left + self.params.right}
        self._commands = ctx.bus.input(self.params.topic, "geometry_msgs/msg/Twist", check_twist)
        tf_topic = self.params.tf_topic if self.params.publish_tf else None
        self._output = OdometryOutput(
            ctx.bus, self.params.odom_topic, tf_topic, self.params.frame_id, self.params.child_frame_id
        )
        self.every = Every.hz(self.params.odom_rate)
        self._target = self._current = (0.0, 0.0)
        self._applied: tuple[float, float] | None = None  # None: the first step holds the wheels still
        self._odom = Odometry()
        self._last_ns = 0
        kinematic = ctx.world.physics.type == KINEMATIC
        self._skid = SkidError() if kinematic else skid_error(self._model, self._physics.step_size)

    @property
    def odometry_frames(self) -> tuple[str, str] | None:
        """(odometry frame, child frame) as it publishes them (prefixed with the robot's namespace); None: no odometry."""
        return (self._output.frame_id, self._output.child_frame_id)

    def pre_update(self, info: UpdateInfo) -> None:
        commands = self._commands.drain()
        if not commands and self._current == self._target == self._applied:
            return  # at its command and applied: nothing to ramp (most of a fleet, most steps)
        for msg in commands:
            self._target = (self.params.linear.clamp(msg.linear.x), self.params.angular.clamp(msg.angular.z))
        dt = self._physics.step_size
        v = self.params.linear.ramp(self._current[0], self._target[0], dt)
        w = self.params.angular.ramp(self._current[1], self._target[1], dt)
        self._current = (v, w)
        if self._current != self._applied:
            self._drive(v, w)

    def _drive(self, v: float, w: float) -> None:
        half = w * self.params.separation / 2
        for joints, speed in ((self.params.left, v - half), (self.params.right, v + half)):
            for joint in joints:
                self._physics.set_joint_velocity(self._name, joint, speed / self.params.radius, self._efforts[joint])
        self._physics.drive_base(self._name, v, 0.0, w)
        self._applied = (v, w)

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self.every.due(now_ns):
            return
        left, right = self._sides()
        distance, turn = self._odom.update(left, right, self.params.radius, self.params.separation)
        dt = (now_ns - self._last_ns) / 1e9
        self._last_ns = now_ns
        speed, rate = (distance / dt, turn / dt) if dt > 0 else (0.0, 0.0)
        covariance = twist_covariance(self._skid, speed, rate)
        self._output.put_planar(now_ns, self._odom.pose, (speed, 0.0), rate, covariance)

    def _sides(self) -> tuple[float, float]:
        """The mean wheel angle of each side, both sides' joints read in one query."""
        left, right = self.params.left, self.params.right
        states = self._physics.joint_states(self._name, [*left, *right])
        return (
            sum(s[0] for s in states[: len(left)]) / len(left),
            sum(s[0] for s in states[len(left) :]) / len(right),
        )

    def reset(self, info: UpdateInfo) -> None:
        self._target = self._current = (0.0, 0.0)
        self._drive(0.0, 0.0)
        self._odom = Odometry()
        self.every.restart()
        self._last_ns = info.sim_time_ns
