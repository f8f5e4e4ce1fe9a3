"""TrajectoryFollower: a model pushed along waypoints in the plane, as gz-sim's TrajectoryFollower does.

A `<plugin>` of a model (a cart, a forklift). Before each step: while the next waypoint lies more
than `bearing_tolerance` off the link's heading, a yaw torque turns the link towards it; once it
lies within, a force along the link's x axis pushes it on; within `range_tolerance` of the
waypoint, the next becomes the goal (with `loop`, the reached one goes to the back of the list;
without, the model stops at the last). Force and torque act on the link's centre of mass for the
one step (Gazebo's AddWorldWrench); the friction, mass and inertia of the model decide how fast
it goes.

| parameter | default | what |
| --- | --- | --- |
| `link_name` | required | the link pushed and turned |
| `waypoints` / `waypoint` | — | x y of each waypoint, world frame (repeatable) |
| `circle` / `radius` | — | else: 8 waypoints on a circle of this radius about the link's start |
| `line` / `direction`, `length` | — | else: from the start, `length` m along `direction` rad (turned by the link's start orientation, as Gazebo's code does) |
| `loop` | false | visit the waypoints for ever |
| `range_tolerance` | 0.5 | m: a waypoint this near is reached |
| `bearing_tolerance` | 2 | degrees: no torque within it |
| `zero_vel_on_bearing_reached` | false | the model's angular velocity set to zero within half the tolerance |
| `force` | 60 | N, along the link's x axis |
| `torque` | 50 | N·m about the link's z axis |
| `topic` | `model/<m>/trajectory_follower/pause` | std_msgs/Bool: true pauses, false resumes |

Only one of `waypoints`, `circle` and `line` is used, in that order, as in Gazebo. Where Gazebo
reads its waypoints at the first step, simbot reads them when the model enters the world (the same
start pose); `reset` starts the list over.
"""

from __future__ import annotations

import math

import numpy as np

from simbot.description.plugin_params import bool_param, number_param, param
from simbot.sim.kit.waypoints import waypoints
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.transform import Transform, Vec3, matmul, norm, quaternion_to_matrix, rotate_into


class TrajectoryFollower:
    """See the module docstring."""

    name = "TrajectoryFollower"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        plugin = ctx.plugin
        model, self._model = ctx.require_model("TrajectoryFollower")
        link = param(plugin, "link_name")
        if link is None or link not in {item.name for item in model.links}:
            raise SystemConfigError(f"{plugin.name}: <link_name> {link!r} is not a link of model {self._model!r}")
        self._link = link
        self._physics = ctx.physics
        start = ctx.physics.frame_pose(self._model, link)
        self._initial = waypoints(plugin, Transform((start.position[0], start.position[1], 0.0), start.orientation))
        self._left = list(self._initial)
        self._loop = bool_param(plugin, "loop", default=False)
        self._force = number_param(plugin, "force", default=60.0) or 0.0
        self._torque = number_param(plugin, "torque", default=50.0) or 0.0
        self._range = number_param(plugin, "range_tolerance", default=0.5) or 0.0
        self._bearing = number_param(plugin, "bearing_tolerance", default=2.0) or 0.0
        self._zero_turn = bool_param(plugin, "zero_vel_on_bearing_reached", default=False)
        topic = param(plugin, "topic") or ctx.model_topic("trajectory_follower/pause")
        self._pause_input = ctx.bus.input(topic.strip("/"), "std_msgs/msg/Bool")
        self._paused = False
        self.reached = 0
        """Waypoints reached since the start (or the last reset)."""

    def pre_update(self, info: UpdateInfo) -> None:
        for msg in self._pause_input.drain():
            self._paused = bool(msg.data)
        if info.paused or self._paused or not self._left:
            return
        pose = self._physics.frame_pose(self._model, self._link)
        goal_x, goal_y = self._left[0]
        local = rotate_into(pose.orientation, (goal_x - pose.position[0], goal_y - pose.position[1], 0.0))
        if norm(local) <= self._range:
            self._next()
            return
        bearing = math.degrees(math.atan2(local[1], local[0]))
        force: Vec3 = (0.0, 0.0, 0.0)
        torque: Vec3 = (0.0, 0.0, 0.0)
        rotation = quaternion_to_matrix(pose.orientation)
        if abs(bearing) <= self._bearing:
            force = _vec(matmul(rotation, (self._force, 0.0, 0.0)))
            if self._zero_turn and abs(bearing) <= self._bearing * 0.5:
                self._stop_turning()
        else:
            torque = _vec(matmul(rotation, (0.0, 0.0, math.copysign(self._torque, bearing))))
        self._physics.apply_wrench(self._model, self._link, force, torque)

    def _next(self) -> None:
        """The goal is reached: the next one, as Gazebo moves on (a lone last waypoint stays the goal)."""
        if len(self._left) == 1:
            return
        self.reached += 1
        reached = self._left.pop(0)
        if self._loop:
            self._left.append(reached)

    def _stop_turning(self) -> None:
        """The model's angular velocity to zero, its linear velocity kept (given in the model frame)."""
        _, linear, _ = self._physics.model_motion(self._model)
        in_model = rotate_into(self._physics.model_pose(self._model).orientation, linear)
        self._physics.set_model_velocity(self._model, in_model, (0.0, 0.0, 0.0))

    def reset(self, info: UpdateInfo) -> None:
        self._left, self._paused, self.reached = list(self._initial), False, 0


def _vec(values: np.ndarray) -> Vec3:
    return float(values[0]), float(values[1]), float(values[2])
