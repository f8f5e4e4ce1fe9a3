"""The drives' parameters, which the drive systems, the gym (its action space, its topics) and
`simbot describe` all read: velocity and acceleration `Limits` as Gazebo's drives state them, and
DiffDrive's whole `<plugin>` (`DiffDriveParams`; its table: simbot/sim/systems/diff_drive.py).

A value that is unusable raises `SystemConfigError` naming the plugin and the tag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from simbot.description.errors import SystemConfigError
from simbot.description.model import Model, Plugin
from simbot.description.naming import model_topic, scoped_key
from simbot.description.plugin_params import bool_param, number_param, param


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

    @property
    def magnitude(self) -> float | None:
        """The most |value| may be: the smaller magnitude of the bounds stated, None where none is."""
        stated = [abs(bound) for bound in (self.max_value, self.min_value) if bound is not None]
        return min(stated) if stated else None


def limits(plugin: Plugin, kind: str | None, legacy: str | None = None) -> Limits:
    """`min_/max_<kind>_velocity` and `_acceleration` (`min_velocity`, ... where `kind` is None, as
    AckermannSteering and MecanumDrive name them); `legacy` an older spelling of the maxima.
    A maximum acceleration alone bounds deceleration likewise."""
    infix = f"{kind}_" if kind else ""
    legacy_velocity = (f"max_{legacy}velocity",) if legacy is not None else ()
    legacy_acceleration = (f"max_{legacy}acceleration",) if legacy is not None else ()
    max_rate = number_param(plugin, f"max_{infix}acceleration", *legacy_acceleration, positive=True)
    min_rate = number_param(plugin, f"min_{infix}acceleration")
    return Limits(
        number_param(plugin, f"min_{infix}velocity"),
        number_param(plugin, f"max_{infix}velocity", *legacy_velocity),
        -max_rate if min_rate is None and max_rate is not None else min_rate,
        max_rate,
    )


@dataclass(frozen=True)
class DiffDriveParams:
    """A DiffDrive's parameters (the table in simbot/sim/systems/diff_drive.py), checked."""

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
