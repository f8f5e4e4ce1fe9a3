"""SocialForce: a person who walks its route and gives way, by Helbing & Molnár's social-force model.

A `<plugin>` of an `<actor>` (`<plugin name="simbot::systems::SocialForce"
filename="simbot-social-force-system">`). It moves the actor in place of its script
(`ActorDriver`): the person walks towards each waypoint of its route in turn and keeps its
distance from other people, from the static world (walls, racks, pillars) and from every body
that moves by itself (the tug, a cart), by the forces of simbot.sim.kit.social_force, in sim time.
The forces and the velocity are updated `update_rate` times a second (every 20 ms: what the
people, walls and tug around do changes little in that time, which is 25 times shorter than τ),
the position at every physics step with that velocity; what each rate costs is measured on the
warehouse with ten people (benchmarks/bench_crowd.py, docs/speed.md). At each update the person
is put back outside the others and the obstacles; at every step it is kept `radius` clear of the
footprints of the robots that were near it at the last update (those that may close in by
CLOSING_SPEED before the next): a person the tug blocks or drives at slows, steps aside or stops,
never walks through it; a robot put onto a person (set_pose) pushes it aside at the next step.

The route: the positions of the actor's own `<script>` waypoints (in the actor's frame, the turns
on the spot dropped), walked from where the script has it at time 0 and looped as the script
loops; or the plugin's `<waypoints>` (x y in the world frame, as TrajectoryFollower reads them,
walked from the same start, looped with `loop`). A route that does not loop ends at its last
waypoint, where the person stands (still giving way).

| parameter | default | source | what |
| --- | --- | --- | --- |
| `desired_speed` | the script's mean speed along its route, else 1.34 | Helbing & Molnár 1995 (v0 1.34 m/s, σ 0.26) | m/s: v0 |
| `relaxation_time` | 0.5 | Helbing & Molnár 1995; Helbing, Farkas & Vicsek 2000 | s: τ, how fast the person takes up v0 |
| `radius` | 0.3 | Helbing, Farkas & Vicsek 2000 (r 0.25–0.35 m) | m: the person's disc (the proxy is 0.25) |
| `max_speed_factor` | 1.3 | Helbing & Molnár 1995 (v_max = 1.3 v0) | the speed never exceeds it times v0 |
| `people_strength` | 2.1 | Helbing & Molnár 1995 (V⁰ 2.1 m²/s²) | m/s²: A between people |
| `people_range` | 0.3 | Helbing & Molnár 1995 (σ 0.3 m) | m: B between people |
| `anisotropy` | 0.5 | Helbing & Molnár 1995 (c 0.5 behind) | λ: weight of who is behind (1: all alike) |
| `obstacle_strength` | 10 | Helbing & Molnár 1995 (U⁰ 10 m²/s²) | m/s²: from walls and static shapes |
| `obstacle_range` | 0.2 | Helbing & Molnár 1995 (R 0.2 m) | m: from walls and static shapes |
| `obstacle_cutoff` | 0.5 | simbot: people walk 0.5 m and more off a rack face without being pushed off their line | m: a gap (beyond the radius) at which an obstacle's force has tapered to nothing |
| `robot_strength` | 2.1 | as people | m/s²: from bodies that move by themselves (their outlines) |
| `robot_range` | 0.4 | simbot: twice a wall's, room for a 2 m machine that may move | m |
| `noise` | 0.05 | simbot (Helbing, Farkas & Vicsek 2000's fluctuation term) | m/s per √s: velocity jitter, breaks ties |
| `turn_rate` | π | simbot | rad/s: the heading turns towards the velocity at most this fast |
| `waypoint_tolerance` | 0.3 | simbot | m: a waypoint this near is reached |
| `update_rate` | 50 | simbot: measured (above) | Hz: how often the forces are updated; the position moves at every step |
| `loop` | the script's | — | the plugin's waypoints: walk them for ever |
| `waypoints`/`waypoint` | the script's | — | x y, world frame |

The forces' strengths are Helbing & Molnár's potentials' V⁰ and U⁰ taken as accelerations at
contact, A·exp((r − d)/B). A value out of range (a negative speed, τ ≤ 0, λ outside 0..1) leaves
the plugin out with one line naming the actor and the element: the actor walks its script.
Obstacles: the collisions of static models reaching into the person's height (from its soles, the
lowest point of its proxy or legs, up PROXY_HEIGHT), each as the rectangle holding its shadow
(meshes are not obstacles); read when the set of bodies changes, and those within CACHE_SLACK of
the obstacles' reach kept until the person has walked CACHE_SLACK. Bodies that move but have no
plugin of their own (a trolley) are obstacles too, read where they stand at each update. Robots,
the moving bodies with plugins (not actors): the same shadows, moved with the body; the force
from the one rectangle holding them. Other people are discs of this person's radius, read from the physics. The jitter is
drawn from this system's own random stream: lockstep runs repeat bit for bit. `set_pose` on the
actor moves its route with it (its start where it was put); `reset` takes it back to its start.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import PROXY_HEIGHT, ActorModel, Script, is_actor
from simbot.description.crowd_params import read_crowd
from simbot.description.footprints import collision_boxes, reaches_into
from simbot.description.model import Model
from simbot.description.plugin_params import bool_param
from simbot.sim.kit.social_force import (
    Boxes,
    Crowd,
    Floats,
    Route,
    Surroundings,
    Walker,
    acceleration,
    detour,
    kept_clear,
    outside,
    steered,
    turned,
)
from simbot.sim.kit.waypoints import waypoints
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.physics import compose
from simbot.sim.physics.protocols import WorldAccess
from simbot.transform import Transform, yaw_quaternion

MOVED_TOLERANCE = 1e-4
"""Metres by which the actor must stand off where it was put to count as moved by world control."""
STEP_HEIGHT = 0.05
"""Metres above the soles below which a shape is stepped over, not walked round (the floor, a mat)."""
CACHE_SLACK = 1.0
"""Metres a person walks before the static shadows near it are sorted again (those within this
more than the obstacles' reach are kept)."""
CLOSING_SPEED = 5.0
"""m/s at which a robot and a person may close in on each other at most (the tug's top speed and a
run, with room): a robot farther than the radius and this for one update period is looked at only
at the next update, a nearer one at every step."""


def script_route(script: Script, frame: Transform) -> tuple[list[tuple[float, float]], float | None]:
    """The script's waypoint positions in the world, and its mean speed along them (None if it does not move)."""
    points = [compose(frame, Transform(w.pose.xyz)).position[:2] for t in script.trajectories for w in t.waypoints]
    duration = sum(t.waypoints[-1].time - t.waypoints[0].time for t in script.trajectories)
    length = sum(math.dist(a, b) for a, b in zip(points, points[1:]))
    return [(p[0], p[1]) for p in points], (length / duration if duration > 0 and length > 0 else None)


def shadows(model: Model, low: float, high: float) -> Boxes:
    """The rectangles holding the shadows of the model's collisions that reach from `low` to `high`
    (heights in the model's frame), in the model's frame."""
    rectangles = []
    for _, _, corners in collision_boxes(model):
        if not reaches_into(corners, low, high):
            continue
        along, across = corners[4] - corners[0], corners[2] - corners[0]
        if abs(along[2]) < 1e-9 and abs(across[2]) < 1e-9:  # upright: its own rectangle
            centre = corners.mean(axis=0)
            yaw = math.atan2(along[1], along[0])
            rectangles.append((centre[0], centre[1], yaw, np.hypot(*along[:2]) / 2, np.hypot(*across[:2]) / 2))
        else:  # tilted (a wheel): the axis-aligned box holding it
            (x0, y0), (x1, y1) = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
            rectangles.append(((x0 + x1) / 2, (y0 + y1) / 2, 0.0, (x1 - x0) / 2, (y1 - y0) / 2))
    return Boxes.of(rectangles)


def _planar(pose: Transform) -> tuple[float, float, float]:
    return pose.position[0], pose.position[1], pose.yaw


class _World:
    """What one person sees of the others: their names by kind, the static shadows, the robots' own."""

    def __init__(self, physics: WorldAccess, me: str, low: float, high: float) -> None:
        self._physics, self._me, self._low, self._high = physics, me, low, high
        self._names: tuple[str, ...] = ()
        self.people: list[str] = []
        self.robots: dict[str, Boxes] = {}
        self.movables: dict[str, Boxes] = {}
        self.obstacles = Boxes.of([])
        self._seen: dict[str, Floats] = {}
        self._outlines: dict[str, Boxes] = {}
        self._near = self.obstacles
        self._near_at: Floats | None = None

    def refresh(self) -> bool:
        """Sorts the bodies again when the world's set of them has changed (a model created or
        removed): whether it had."""
        names = tuple(self._physics.body_names())
        if names == self._names:
            return False
        self._names, self._near_at = names, None
        moving = set(self._physics.moving_bodies())
        self.people, self.robots, self.movables, self._outlines, static = [], {}, {}, {}, []
        for name in names:
            model = self._physics.model_of(name)
            if isinstance(model, ActorModel):
                if name != self._me:
                    self.people.append(name)
                continue
            pose = self._physics.model_pose(name)
            boxes = shadows(model, self._low - pose.position[2], self._high - pose.position[2])
            if name in moving and model.plugins and len(boxes):  # moves by itself, at the person's height
                self.robots[name], self._outlines[name] = boxes, boxes.outline()
            elif name in moving:
                self.movables[name] = boxes
            else:
                static.append(boxes.placed(*_planar(pose)))
        self.obstacles = Boxes.joined(static)
        return True

    def obstacles_near(self, point: Floats, reach: float) -> Boxes:
        """The static shadows within `reach` of `point` (those within `reach` + CACHE_SLACK of where
        they were last sorted, sorted again once the person is CACHE_SLACK from there), and the
        movable bodies' where they stand now."""
        if self._near_at is None or float(np.hypot(*(point - self._near_at))) > CACHE_SLACK:
            self._near, self._near_at = self.obstacles.within(point, reach + CACHE_SLACK), point.copy()
        if not self.movables:
            return self._near
        placed = [boxes.placed(*_planar(self._physics.model_pose(name))) for name, boxes in self.movables.items()]
        return Boxes.joined([self._near, *(boxes.within(point, reach) for boxes in placed)])

    def robots_at(self, names: list[str]) -> Boxes:
        """The footprints of the robots `names` where they stand now."""
        return Boxes.joined([self.robots[n].placed(*_planar(self._physics.model_pose(n))) for n in names])

    def outlines_at(self, names: list[str]) -> Boxes:
        """The outlines of the robots `names` where they stand now."""
        return Boxes.joined([self._outlines[n].placed(*_planar(self._physics.model_pose(n))) for n in names])

    def around(self, point: Floats, crowd: Crowd, dt: float, margin: float) -> tuple[Surroundings, list[str]]:
        """The people (their velocities from where they were `dt` s ago), the obstacles and the robots'
        outlines near `point` (no footprints: the robots within `margin` of it, the names returned,
        are kept clear at every step), and the robots whose outlines lie within `margin` of it."""
        reach = crowd.reach
        now = {name: np.array(self._physics.model_pose(name).position[:2]) for name in self.people}
        close = [name for name, at in now.items() if float(np.hypot(*(at - point))) <= reach]
        people = np.array([now[name] for name in close]).reshape(-1, 2)
        motions = np.array([(now[n] - self._seen[n]) / dt if n in self._seen else np.zeros(2) for n in close])
        self._seen = now
        outlines = self.outlines_at(list(self.robots))
        touching = [name for name, gap in zip(self.robots, outlines.nearest(point)[0]) if gap < margin]
        near = self.obstacles_near(point, crowd.obstacle_reach)
        return Surroundings(people, motions.reshape(-1, 2), near, Boxes.of([]), outlines.within(point, reach)), touching


def _height(model: Model, frame: Transform) -> tuple[float, float]:
    """The world heights a person takes up: from its soles (the lowest point of its collisions, the
    proxy's or the legs' of an animated skin, as they stand in the SDF; else its frame) up PROXY_HEIGHT."""
    lowest = [float(corners[:, 2].min()) for _, _, corners in collision_boxes(model)]
    feet = frame.position[2] + (min(lowest) if lowest else 0.0)
    return feet + STEP_HEIGHT, feet + PROXY_HEIGHT


class SocialForce:
    """See the module docstring."""

    name = "SocialForce"
    drives_actor = True
    """Moves its actor in place of the script (simbot.sim.kit.actor_driver.ActorDriver)."""

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._actor = ctx.require_model("SocialForce")
        plugin = ctx.plugin
        if not is_actor(model):
            raise SystemConfigError(f"{plugin.name}: SocialForce belongs in an <actor>, not in model {self._actor!r}")
        assert isinstance(model, ActorModel)
        frame = ctx.physics.model_pose(self._actor)
        points, speed = script_route(model.script, frame)
        self._crowd = read_crowd(plugin, self._actor, speed)
        start = compose(frame, ScriptPath.of(model.script).pose_at(0.0))
        listed = waypoints(plugin, start)
        try:
            loop = bool_param(plugin, "loop", default=model.script.loop)
        except SystemConfigError as exc:
            raise SystemConfigError(f"actor {self._actor!r}: {exc}; it walks its script") from None
        self._initial_route = Route.of(listed or points or [start.position[:2]], loop)
        self._height = self._initial_height = start.position[2]
        self._initial = Walker(np.array(start.position[:2]), np.zeros(2), start.yaw)
        self._initial_goal = self._initial_route.ahead(self._initial.position, self._crowd.waypoint_tolerance)
        self._physics, self._rng = ctx.physics, ctx.rng
        self._world = _World(ctx.physics, self._actor, *_height(model, frame))
        self._route, self._walker, self._goal, self._last_ns = self._initial_route, self._initial, self._initial_goal, 0
        self._period_ns = max(1, round(1e9 / self._crowd.update_rate))
        self._anchor, self._touching = self._initial.position, list[str]()
        self._thought_ns: int | None = None
        self._put = self._place()

    def pre_update(self, info: UpdateInfo) -> None:
        """One physics step: the forces again where an update is due (or the world changed), then
        the position moved on with the velocity, kept clear of the robots, and the actor put there."""
        dt = (info.sim_time_ns - self._last_ns) / 1e9
        if info.paused or dt <= 0:
            return
        self._last_ns = info.sim_time_ns
        self._follow_teleport()
        changed = self._world.refresh()
        if changed or self._thought_ns is None or info.sim_time_ns - self._thought_ns >= self._period_ns:
            self._think(info.sim_time_ns)
        walker, crowd = self._walker, self._crowd
        position = walker.position + walker.velocity * dt
        if self._touching:
            position = outside(crowd, position, self._world.robots_at(self._touching))
        self._walker = Walker(position, walker.velocity, turned(crowd, walker.yaw, walker.velocity, dt))
        self._put = self._place()

    def _think(self, now_ns: int) -> None:
        """The social force from where everyone stands now, the velocity steered by it over the update
        period (semi-implicit Euler), the person put back outside people and obstacles."""
        crowd, period = self._crowd, self._period_ns / 1e9
        span = period if self._thought_ns is None else (now_ns - self._thought_ns) / 1e9
        self._thought_ns = now_ns
        walker = replace(self._walker, velocity=(self._walker.position - self._anchor) / span)
        around, self._touching = self._world.around(walker.position, crowd, span, crowd.radius + CLOSING_SPEED * period)
        self._goal = self._route.after(self._goal, walker.position, crowd.waypoint_tolerance)
        goal = self._route.points[self._goal]
        heading = detour(crowd, walker.position, goal, around.outlines)
        arriving = self._route.arriving(self._goal) and heading is goal
        accel = acceleration(crowd, walker, heading, arriving, around)
        kick = self._rng.standard_normal(2) * (crowd.noise * math.sqrt(span))
        velocity = steered(crowd, walker.velocity, accel, span, kick)
        position = kept_clear(crowd, walker.position, around)
        self._walker, self._anchor = replace(walker, position=position, velocity=velocity), position

    def reset(self, info: UpdateInfo) -> None:
        """Back at its start, at rest, its route as the SDF gives it."""
        self._route, self._walker, self._goal = self._initial_route, self._initial, self._initial_goal
        self._height, self._last_ns = self._initial_height, info.sim_time_ns
        self._anchor, self._thought_ns, self._touching = self._initial.position, None, []
        self._put = self._place()

    def _place(self) -> Transform:
        (x, y), yaw = self._walker.position, self._walker.yaw
        pose = Transform((float(x), float(y), self._height), yaw_quaternion(yaw))
        self._physics.set_model_pose(self._actor, pose)
        return pose

    def _follow_teleport(self) -> None:
        """Put elsewhere (world control's set_pose): at rest there, its route moved with it."""
        now = self._physics.model_pose(self._actor)
        if math.dist(now.position, self._put.position) <= MOVED_TOLERANCE:
            return
        shift = np.array(now.position[:2]) - self._walker.position
        self._route = Route(self._route.points + shift, self._route.loop)
        self._walker = Walker(np.array(now.position[:2]), np.zeros(2), now.yaw)
        self._anchor, self._thought_ns, self._height = self._walker.position, None, now.position[2]
