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

from simbot.description.model import Param, Plugin
from simbot.sim.kit.plugin_params import bool_param, number_param, param
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.transform import Transform, Vec3, matmul, norm, quaternion_to_matrix, rotate_into

CIRCLE_SAMPLES = 8
"""Waypoints of a `<circle>` (Gazebo's numSamples)."""


def _child(params: tuple[Param, ...], tag: str) -> Param | None:
    return next((p for p in params if p.tag == tag), None)


def _number(plugin: Plugin, block: Param, tag: str) -> float:
    found = _child(block.children, tag)
    if found is None:
        raise SystemConfigError(f"{plugin.name}: <{block.tag}><{tag}> is required")
    try:
        return float(found.text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{block.tag}><{tag}> expected a number, got {found.text!r}") from None


def waypoints(plugin: Plugin, start: Transform) -> list[tuple[float, float]]:
    """The waypoints the plugin states (`waypoints`, else `circle`, else `line`), in the world frame."""
    listed, circle, line = (_child(plugin.params, tag) for tag in ("waypoints", "circle", "line"))
    if listed is not None:
        points = []
        for point in (p for p in listed.children if p.tag == "waypoint"):
            values = point.text.split()
            try:
                x, y = (float(v) for v in values)
            except ValueError:
                raise SystemConfigError(f"{plugin.name}: <waypoint> expected 'x y', got {point.text!r}") from None
            points.append((x, y))
        if not points:
            raise SystemConfigError(f"{plugin.name}: <waypoints> holds no <waypoint>")
        return points
    x0, y0, _ = start.position
    if circle is not None:
        radius = _number(plugin, circle, "radius")
        angles = [2 * math.pi * i / CIRCLE_SAMPLES for i in range(CIRCLE_SAMPLES)]
        return [(x0 + radius * math.cos(a), y0 + radius * math.sin(a)) for a in angles]
    if line is not None:
        direction, length = _number(plugin, line, "direction"), _number(plugin, line, "length")
        step = (length * math.cos(direction), length * math.sin(direction), 0.0)
        end = matmul(quaternion_to_matrix(start.orientation), step)
        return [(x0, y0), (x0 + float(end[0]), y0 + float(end[1]))]
    return []


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
