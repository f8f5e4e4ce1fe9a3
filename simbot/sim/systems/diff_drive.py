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
turn, a wall) `odom` drifts from the ground truth on `model/<name>/pose`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from simbot.description.model import Model, Plugin
from simbot.sim.kit.drive import Limits, OdometryOutput, PlanarPose, check_twist, joint_effort, limits
from simbot.sim.kit.plugin_params import bool_param, number_param, param
from simbot.sim.kit.rates import Every
from simbot.sim.loop.naming import model_topic, scoped_key
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


@dataclass(frozen=True)
class DiffDriveParams:
    left: tuple[str, ...]
    right: tuple[str, ...]
    separation: float
    radius: float
    topic: str
    odom_topic: str
    tf_topic: str
    frame_id: str
    child_frame_id: str
    odom_rate: float
    publish_tf: bool
    linear: Limits
    angular: Limits

    @staticmethod
    def parse(plugin: Plugin, model: Model, name: str) -> DiffDriveParams:
        """The plugin's parameters; `name` is the model's name in the running world, which Gazebo's
        default keys and frames carry."""
        left, right = tuple(plugin.get_all("left_joint")), tuple(plugin.get_all("right_joint"))
        if not left or not right:
            raise SystemConfigError(f"{plugin.name}: needs at least one <left_joint> and one <right_joint>")
        for joint in left + right:
            if joint not in {j.name for j in model.joints}:
                raise SystemConfigError(f"{plugin.name}: model {model.name!r} has no joint {joint!r}")
        separation = number_param(plugin, "wheel_separation", positive=True)
        radius = number_param(plugin, "wheel_radius", positive=True)
        if separation is None or radius is None:
            raise SystemConfigError(f"{plugin.name}: <wheel_separation> and <wheel_radius> are required")
        frame = scoped_key(name)
        return DiffDriveParams(
            left, right, separation, radius,
            topic=param(plugin, "topic") or model_topic(name, "cmd_vel"),
            odom_topic=param(plugin, "odom_topic") or model_topic(name, "odometry"),
            tf_topic=param(plugin, "tf_topic") or model_topic(name, "tf"),
            frame_id=param(plugin, "frame_id", "odometry_frame") or f"{frame}/odom",
            child_frame_id=param(plugin, "child_frame_id", "base_frame") or f"{frame}/{model.canonical_link}",
            odom_rate=number_param(plugin, "odom_publish_frequency", "update_rate", default=50.0, positive=True) or 50.0,
            publish_tf=bool_param(plugin, "publish_tf", "broadcast_TF", default=True),
            linear=limits(plugin, "linear", ""),
            angular=limits(plugin, "angular"),
        )  # fmt: skip


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


class DiffDrive:
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
        self._every = Every.hz(self.params.odom_rate)
        self._target = self._current = (0.0, 0.0)
        self._applied: tuple[float, float] | None = None  # None: the first step holds the wheels still
        self._odom = Odometry()
        self._last_ns = 0

    @property
    def odometry_frames(self) -> tuple[str, str] | None:
        """(odometry frame, child frame) as it publishes them (prefixed with the robot's namespace); None: no odometry."""
        return (self._output.frame_id, self._output.child_frame_id)

    def pre_update(self, info: UpdateInfo) -> None:
        for msg in self._commands.drain():
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
        if not self._every.due(now_ns):
            return
        distance, turn = self._odom.update(
            self._side(self.params.left), self._side(self.params.right), self.params.radius, self.params.separation
        )
        dt = (now_ns - self._last_ns) / 1e9
        self._last_ns = now_ns
        speed, rate = (distance / dt, turn / dt) if dt > 0 else (0.0, 0.0)
        self._output.put_planar(now_ns, self._odom.pose, (speed, 0.0), rate)

    def _side(self, joints: tuple[str, ...]) -> float:
        states = self._physics.joint_states(self._name, list(joints))
        return sum(s[0] for s in states) / len(states)

    def reset(self, info: UpdateInfo) -> None:
        self._target = self._current = (0.0, 0.0)
        self._drive(0.0, 0.0)
        self._odom = Odometry()
        self._every.restart()
        self._last_ns = info.sim_time_ns
