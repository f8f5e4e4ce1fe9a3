"""OdometryPublisher: a model's true pose and velocity as odometry (Gazebo's OdometryPublisher).

| parameter | default |
|---|---|
| `odom_frame` | `<model>/odom` |
| `robot_base_frame` | `<model>/base_footprint` |
| `odom_publish_frequency` | 50 Hz |
| `odom_topic` | `model/<model>/odometry` |
| `odom_covariance_topic` | `model/<model>/odometry_with_covariance` |
| `tf_topic` | `model/<model>/tf` (Gazebo's is `model/<model>/pose`, simbot's ground-truth PoseStamped key) |
| `dimensions` | 2 (2 or 3) |
| `xyz_offset`, `rpy_offset` | 0 0 0: the frame reported, in the model frame |
| `gaussian_noise` | 0: σ added to each twist component, σ² on the covariance diagonals |

The pose is the world pose of the model frame moved by the offset, unlike a drive's dead
reckoning: it never drifts. The twist is that frame's velocity in its own axes; in 2
dimensions z is left out, the linear velocity is taken in the heading's axes and z, roll and
pitch rates are noise alone, as in Gazebo. In ROS 2 both outputs are nav_msgs/Odometry,
with the same content (Gazebo's gz.msgs.Odometry has no covariance).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.naming import scoped_key
from simbot.description.plugin_params import number_param, param
from simbot.description.poses import Pose
from simbot.sim.kit.drive import OdometryOutput, diagonal, vector_param
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.physics import compose, pose_to_transform
from simbot.transform import Transform, rotate_into, yaw_of


class OdometryPublisher(Paced):
    """Publishes the model's ground-truth odometry at its rate."""

    name = "OdometryPublisher"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        plugin = ctx.plugin
        _, self._name = ctx.require_model("OdometryPublisher")
        frame = scoped_key(self._name)
        self._dimensions = number_param(plugin, "dimensions", default=2.0)
        if self._dimensions not in (2.0, 3.0):
            raise SystemConfigError(f"{plugin.name}: <dimensions> must be 2 or 3, got {self._dimensions:g}")
        self._offset = pose_to_transform(Pose(vector_param(plugin, "xyz_offset"), vector_param(plugin, "rpy_offset")))
        self._noise = number_param(plugin, "gaussian_noise", default=0.0) or 0.0
        if self._noise < 0:
            raise SystemConfigError(f"{plugin.name}: <gaussian_noise> must not be negative, got {self._noise:g}")
        self._output = OdometryOutput(
            ctx.bus,
            param(plugin, "odom_topic") or ctx.model_topic("odometry"),
            param(plugin, "tf_topic") or ctx.model_topic("tf"),
            param(plugin, "odom_frame") or f"{frame}/odom",
            param(plugin, "robot_base_frame") or f"{frame}/base_footprint",
        )
        covariance_topic = param(plugin, "odom_covariance_topic") or ctx.model_topic("odometry_with_covariance")
        self._covariance_pub = ctx.bus.publisher(covariance_topic, messages.Odometry)
        rate = number_param(plugin, "odom_publish_frequency", default=50.0, positive=True) or 50.0
        self.every = Every.hz(rate)
        self._physics = ctx.physics
        self._rng = ctx.rng

    def post_update(self, info: UpdateInfo) -> None:
        if not self.every.due(info.sim_time_ns):
            return
        (xyz, quat), linear, angular = self._motion()
        if self._dimensions == 2:
            yaw = yaw_of(quat)
            c, s = math.cos(yaw), math.sin(yaw)
            twist = np.array([c * linear[0] + s * linear[1], c * linear[1] - s * linear[0], 0.0, 0.0, 0.0, angular[2]])
            xyz = (xyz[0], xyz[1], 0.0)
        else:
            twist = np.array([*rotate_into(quat, linear), *rotate_into(quat, angular)])
        twist += self._rng.normal(0.0, self._noise, 6) if self._noise else 0.0
        covariance = diagonal((self._noise**2,) * 6)
        twist_xyz = (float(twist[0]), float(twist[1]), float(twist[2]))
        rates = (float(twist[3]), float(twist[4]), float(twist[5]))
        self._output.put(
            info.sim_time_ns, (xyz, quat), (twist_xyz, rates), covariance, covariance, also=self._covariance_pub
        )

    def _motion(self) -> tuple[Transform, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The offset frame's world pose, and its linear and angular velocity in the world."""
        frame, linear, angular = self._physics.model_motion(self._name)
        pose = compose(frame, self._offset)
        lever = np.subtract(pose[0], frame[0])
        return pose, np.add(linear, np.cross(angular, lever)), np.asarray(angular, dtype=float)

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
