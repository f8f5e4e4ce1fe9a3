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

import math
from dataclasses import dataclass
from typing import Any

from simbot.bus import messages
from simbot.description.model import Model, Plugin
from simbot.sim.system import (
    Every,
    SystemConfigError,
    SystemContext,
    UpdateInfo,
    bool_param,
    model_topic,
    number_param,
    param,
    scoped_key,
)

ABSURD_SPEED = 100.0
"""m/s or rad/s beyond which a command is malformed, not merely fast: it is dropped, not clamped."""
POSE_COVARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
TWIST_COVARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
"""Diagonals (x, y, z, roll, pitch, yaw): planar odometry knows nothing of z, roll and pitch."""


@dataclass(frozen=True)
class Limits:
    """Bounds on commanded velocity and its change; None where the SDF sets none."""

    min_value: float | None = None
    max_value: float | None = None
    min_rate: float | None = None
    max_rate: float | None = None

    def clamp(self, value: float) -> float:
        low = -math.inf if self.min_value is None else self.min_value
        high = math.inf if self.max_value is None else self.max_value
        return min(max(value, low), high)

    def ramp(self, current: float, target: float, dt: float) -> float:
        """`target`, reached no faster than the acceleration limits allow."""
        up = math.inf if self.max_rate is None else self.max_rate * dt
        down = -math.inf if self.min_rate is None else self.min_rate * dt
        return current + min(max(target - current, down), up)


def _limits(plugin: Plugin, kind: str, legacy: str | None) -> Limits:
    legacy_velocity = (f"max_{legacy}velocity",) if legacy is not None else ()
    legacy_acceleration = (f"max_{legacy}acceleration",) if legacy is not None else ()
    max_rate = number_param(plugin, f"max_{kind}_acceleration", *legacy_acceleration, positive=True)
    min_rate = number_param(plugin, f"min_{kind}_acceleration")
    return Limits(
        number_param(plugin, f"min_{kind}_velocity"),
        number_param(plugin, f"max_{kind}_velocity", *legacy_velocity),
        -max_rate if min_rate is None and max_rate is not None else min_rate,
        max_rate,
    )


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
            linear=_limits(plugin, "linear", ""),
            angular=_limits(plugin, "angular", None),
        )  # fmt: skip


def check_twist(msg: Any) -> str | None:
    """Why a Twist is no command: NaN, infinite or absurd components."""
    values = (msg.linear.x, msg.linear.y, msg.linear.z, msg.angular.x, msg.angular.y, msg.angular.z)
    if not all(math.isfinite(v) for v in values):
        return f"non-finite velocity {values}"
    if abs(msg.linear.x) > ABSURD_SPEED or abs(msg.angular.z) > ABSURD_SPEED:
        return f"absurd velocity: linear.x {msg.linear.x}, angular.z {msg.angular.z} (limit {ABSURD_SPEED})"
    return None


@dataclass
class Odometry:
    """Dead reckoning from the mean encoder angle of each side: each update is an exact circular arc."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
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
        end = self.yaw + turn
        if abs(turn) > 1e-9:
            self.x += distance / turn * (math.sin(end) - math.sin(self.yaw))
            self.y -= distance / turn * (math.cos(end) - math.cos(self.yaw))
        else:
            self.x += distance * math.cos(self.yaw)
            self.y += distance * math.sin(self.yaw)
        self.yaw = math.atan2(math.sin(end), math.cos(end))
        return distance, turn


class DiffDrive:
    """Drives both wheels of each side at v ∓ ω·separation/2 over the radius; publishes odometry."""

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        self._model, self._name = ctx.require_model("DiffDrive")
        self.params = DiffDriveParams.parse(ctx.plugin, self._model, self._name)
        self._physics = ctx.physics
        self._efforts = {j: self._effort(j) for j in self.params.left + self.params.right}
        self._commands = ctx.bus.input(self.params.topic, "geometry_msgs/msg/Twist", check_twist)
        self._odom_pub = ctx.bus.publisher(self.params.odom_topic, messages.Odometry)
        self._tf_pub = ctx.bus.publisher(self.params.tf_topic, messages.TFMessage) if self.params.publish_tf else None
        self._every = Every.hz(self.params.odom_rate)
        self._target = self._current = (0.0, 0.0)
        self._applied: tuple[float, float] | None = None  # None: the first step holds the wheels still
        self._odom = Odometry()
        self._last_ns = 0

    def _effort(self, joint: str) -> float:
        axis = self._model.joint(joint).axis
        return axis.effort if axis is not None and axis.effort is not None else 1e16

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
        self._publish(now_ns, speed, rate)

    def _side(self, joints: tuple[str, ...]) -> float:
        states = self._physics.joint_states(self._name, list(joints))
        return sum(s[0] for s in states) / len(states)

    def _publish(self, now_ns: int, speed: float, rate: float) -> None:
        p, o = self.params, self._odom
        quat = (0.0, 0.0, math.sin(o.yaw / 2), math.cos(o.yaw / 2))
        pose_cov = _diagonal(POSE_COVARIANCE)
        twist_cov = _diagonal(TWIST_COVARIANCE)
        odom = messages.odometry(
            now_ns,
            p.frame_id,
            p.child_frame_id,
            (o.x, o.y, 0.0),
            quat,
            (speed, 0.0, 0.0),
            (0.0, 0.0, rate),
            pose_cov,
            twist_cov,
        )
        self._odom_pub.put(odom)
        if self._tf_pub is not None:
            transform = messages.transform_stamped(now_ns, p.frame_id, p.child_frame_id, (o.x, o.y, 0.0), quat)
            self._tf_pub.put(messages.tf_message([transform]))

    def reset(self, info: UpdateInfo) -> None:
        self._target = self._current = (0.0, 0.0)
        self._drive(0.0, 0.0)
        self._odom = Odometry()
        self._every.restart()
        self._last_ns = info.sim_time_ns


def _diagonal(values: tuple[float, ...]) -> list[float]:
    """A row-major 6×6 covariance with `values` on its diagonal."""
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[i * 7] = value
    return matrix
