"""FollowActor: an actor walks after a target model, as gz-sim's FollowActor system moves it.

A `<plugin>` of an `<actor>` (gz-sim's follow_actor.sdf). Before each step the actor turns to face
its target and walks `velocity` · dt straight at it, on the floor plane, while the target is farther
than `min_distance` and no farther than `max_distance`; it stops (and logs it once) when the target
goes out of range, and starts again when it comes back, as Gazebo's does. Its script is not played:
this system moves the actor in its place (`ActorDriver`), as Gazebo's TrajectoryPose overrides it.

| parameter | default | what |
| --- | --- | --- |
| `target` | required | the model followed (a model of the world when the actor is built) |
| `min_distance` | 1.2 | m: stops this close (planar distance) |
| `max_distance` | 4.0 | m: does not follow a target farther away |
| `velocity` | 0.8 | m/s |
| `animation` | the actor's first | accepted, unused: the skin is not animated here |
| `animation_x_vel` | 2.0 | accepted, unused: the skin is not animated here |

As in gz-sim, the actor keeps the height of its SDF `<pose>` and walks on the plane: it stands
where its `<pose>` put it until it first moves, then faces the target (gz-sim also composes the
`<pose>`'s rotation once more, which turns a rotated actor twice; simbot does not). `set_pose` puts
it elsewhere and it follows from there; `reset` takes it back.
"""

from __future__ import annotations

import logging
import math

from simbot.description.actor_scripts import is_actor
from simbot.description.plugin_params import number_param, param
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.physics import compose
from simbot.transform import Transform, yaw_quaternion

log = logging.getLogger(__name__)

MOVED_TOLERANCE = 1e-4
"""Metres by which the actor must stand off where it was put to count as moved by world control
(PyBullet's transforms round to single precision, a few µm at tens of metres)."""


class FollowActor:
    """See the module docstring."""

    name = "FollowActor"
    drives_actor = True
    """Moves its actor in place of the script (simbot.sim.kit.actor_driver.ActorDriver)."""

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._actor = ctx.require_model("FollowActor")
        plugin = ctx.plugin
        if not is_actor(model):
            raise SystemConfigError(f"{plugin.name}: FollowActor belongs in an <actor>, not in model {self._actor!r}")
        target = param(plugin, "target")
        if target is None:
            raise SystemConfigError(f"{plugin.name}: <target> is required (the model to follow)")
        if target not in ctx.physics.body_names():
            raise SystemConfigError(f"{plugin.name}: <target> {target!r} is not a model of the world")
        self._target = target
        self._velocity = number_param(plugin, "velocity", default=0.8) or 0.0
        self._min = number_param(plugin, "min_distance", default=1.2) or 0.0
        self._max = number_param(plugin, "max_distance", default=4.0) or 0.0
        self._physics = ctx.physics
        start = ctx.physics.model_pose(self._actor)
        self._origin = Transform((0.0, 0.0, start.position[2]))
        self._initial = Transform((start.position[0], start.position[1], 0.0), start.orientation)
        self._path = self._initial
        self._last_ns = 0
        self._following = True
        self._put: Transform | None = None

    def pre_update(self, info: UpdateInfo) -> None:
        if info.paused:
            return
        dt = (info.sim_time_ns - self._last_ns) / 1e9
        self._last_ns = info.sim_time_ns
        self._follow_teleport()
        (x, y, _), _ = self._path
        tx, ty, _ = self._physics.model_pose(self._target).position
        dx, dy = tx - x, ty - y
        distance = math.hypot(dx, dy)
        if distance <= self._min or not self._in_range(distance):
            return
        step = self._velocity * dt / distance
        yaw = math.atan2(dy, dx)
        self._path = Transform((x + dx * step, y + dy * step, 0.0), yaw_quaternion(yaw))
        self._place()

    def _in_range(self, distance: float) -> bool:
        """Whether the target is near enough to follow; a change is logged once, as Gazebo does."""
        near = distance <= self._max
        if near != self._following:
            log.info(
                "%s: target %s %s", self._actor, self._target, "within range: following" if near else "too far: stopped"
            )
            self._following = near
        return near

    def _place(self) -> None:
        self._put = compose(self._origin, self._path)
        self._physics.set_model_pose(self._actor, self._put)

    def _follow_teleport(self) -> None:
        """The actor put elsewhere (world control's set_pose) follows on from there."""
        if self._put is None:
            return
        now = self._physics.model_pose(self._actor)
        if math.dist(now.position, self._put.position) > MOVED_TOLERANCE:
            self._path = Transform((now.position[0], now.position[1], 0.0), self._path.orientation)

    def reset(self, info: UpdateInfo) -> None:
        self._path, self._last_ns, self._following, self._put = self._initial, info.sim_time_ns, True, None
        self._place()
