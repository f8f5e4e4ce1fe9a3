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
from the one rectangle holding them (`simbot.sim.kit.crowd_view` sorts them). Other people are
discs of this person's radius, read from the physics, their velocities from where they stood at this
person's last update (none at the first after a model entered or left). The jitter is drawn from
this system's own random stream: lockstep runs repeat bit for bit.

A world's people are stepped together (`pre_update_all`): the bodies are read once a step for all
of them, and those due update their forces in one pass of the kit's arrays, each with its own
parameters, so that what a person costs falls as the crowd grows (docs/speed.md, "The crowd").
Worlds that step together (a vector env's sub-envs) think in the same pass, each person seeing
only its own world.
`set_pose` on the actor moves its route with it (its start where it was put); `reset` takes it
back to its start.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import PROXY_HEIGHT, ActorModel, Script, is_actor
from simbot.description.crowd_params import read_crowd
from simbot.description.footprints import collision_boxes
from simbot.description.model import Model
from simbot.description.plugin_params import bool_param
from simbot.sim.kit.crowd_view import Band, Poses, View
from simbot.sim.kit.social_force import (
    Bools,
    Boxes,
    Floats,
    Ints,
    Params,
    People,
    Route,
    Surroundings,
    accelerations,
    block_diagonal,
    detours,
    kept_clear,
    outside,
    steered,
    turned,
)
from simbot.sim.kit.waypoints import waypoints
from simbot.sim.loop.system import Batch, SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.physics import compose
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


def _height(model: Model, frame: Transform) -> tuple[float, float]:
    """The world heights a person takes up: from its soles (the lowest point of its collisions, the
    proxy's or the legs' of an animated skin, as they stand in the SDF; else its frame) up PROXY_HEIGHT."""
    lowest = [float(corners[:, 2].min()) for _, _, corners in collision_boxes(model)]
    feet = frame.position[2] + (min(lowest) if lowest else 0.0)
    return feet + STEP_HEIGHT, feet + PROXY_HEIGHT


class SocialForce:
    """See the module docstring. The loop steps a world's people together (`pre_update_all`): they
    think in one pass of the kit's arrays, each with its own parameters, route and random stream."""

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
        self._start = (np.array(start.position[:2]), start.yaw)
        self._initial_goal = self._initial_route.ahead(self._start[0], self._crowd.waypoint_tolerance)
        self._physics, self._rng = ctx.physics, ctx.rng
        self._band = _height(model, frame)
        self._view = View(ctx.physics)
        """The world as its people see it: the first person's serves them all (`pre_update_all`)."""
        self._period_ns = max(1, round(1e9 / self._crowd.update_rate))
        self._seen: tuple[tuple[str, ...], Floats] = ((), np.zeros((0, 2)))
        """Whom it saw at its last think, and where."""
        self._near: Ints = np.zeros(0, np.int64)
        """The static shadows of its band within the obstacles' reach and CACHE_SLACK of `_near_at`."""
        self._near_at: Floats | None = None
        self._touching: list[str] = []
        self._dt = 0.0
        self._thought_ns: int | None = None
        self._restart(0)

    def _restart(self, now_ns: int) -> None:
        """At its start, at rest, its route as the SDF gives it."""
        self._route, self._goal = self._initial_route, self._initial_goal
        self._position, self._yaw = self._start[0].copy(), self._start[1]
        self._velocity = np.zeros(2)
        self._height, self._last_ns = self._initial_height, now_ns
        self._anchor, self._thought_ns, self._touching = self._position, None, []
        self._put = self._place()

    def pre_update(self, info: UpdateInfo) -> None:
        type(self).pre_update_all([Batch([self], info)])

    @classmethod
    def pre_update_all(cls, batches: Sequence[Batch]) -> None:
        """One physics step of each world's people: the forces again for those due (or all of a world
        that changed), every world's in one pass; then every position moved on with its velocity,
        kept clear of the robots, and each actor put there."""
        walking: list[WorldStep] = []
        due: list[WorldStep] = []
        for batch in batches:
            world = _world_step(batch)
            if world is not None:
                walking.append(world)
                if thinking := [p for p in world.people if world.changed or p._due(world.now_ns)]:
                    due.append(world._replace(people=thinking))
        if due:
            _think(due)
        if walking:
            _walk(walking)

    def _ticked(self, info: UpdateInfo) -> bool:
        """Whether sim time moved on since this person's last step (its `_dt`, s)."""
        self._dt = (info.sim_time_ns - self._last_ns) / 1e9
        if info.paused or self._dt <= 0:
            return False
        self._last_ns = info.sim_time_ns
        return True

    def _due(self, now_ns: int) -> bool:
        return self._thought_ns is None or now_ns - self._thought_ns >= self._period_ns

    def _span(self, now_ns: int) -> float:
        """Seconds since its last think (an update period at the first), now its last."""
        span = self._period_ns / 1e9 if self._thought_ns is None else (now_ns - self._thought_ns) / 1e9
        self._thought_ns = now_ns
        return span

    def _static_near(self, band: Band) -> Boxes:
        """The static shadows near it: those within the obstacles' reach and CACHE_SLACK of where they
        were last sorted, sorted again once it has walked CACHE_SLACK from there."""
        point = self._position
        if self._near_at is None or float(np.hypot(*(point - self._near_at))) > CACHE_SLACK:
            reach = self._crowd.obstacle_reach + CACHE_SLACK
            self._near, self._near_at = np.flatnonzero(band.obstacles.within(point, reach)), point.copy()
        return band.obstacles.take(self._near)

    def _motions(self, names: tuple[str, ...], at: Floats, span: float) -> Floats:
        """Each of `names`' velocity since this person last looked, where they stand `at` now (none
        at its first look, or the first after a model entered or left)."""
        motions = (at - self._seen[1]) / span if self._seen[0] == names else np.zeros_like(at)
        self._seen = (names, at)
        return motions

    def reset(self, info: UpdateInfo) -> None:
        """Back at its start, at rest, its route as the SDF gives it."""
        self._seen, self._near_at = ((), np.zeros((0, 2))), None
        self._restart(info.sim_time_ns)

    def _place(self) -> Transform:
        (x, y), yaw = self._position, self._yaw
        pose = Transform((float(x), float(y), self._height), yaw_quaternion(float(yaw)))
        self._physics.set_model_pose(self._actor, pose)
        return pose

    def _follow_teleport(self) -> None:
        """Put elsewhere (world control's set_pose): at rest there, its route moved with it."""
        now = self._physics.model_pose(self._actor)
        if math.dist(now.position, self._put.position) <= MOVED_TOLERANCE:
            return
        shift = np.array(now.position[:2]) - self._position
        self._route = Route(self._route.points + shift, self._route.loop)
        self._position, self._velocity, self._yaw = np.array(now.position[:2]), np.zeros(2), now.yaw
        self._anchor, self._thought_ns, self._height = self._position, None, now.position[2]
        self._near_at = None


class WorldStep(NamedTuple):
    """One world's people in a step: those who walk in it, its sim time, its bodies' poses, and
    whether its set of bodies changed (all think again)."""

    people: list[SocialForce]
    now_ns: int
    poses: Poses
    changed: bool


def _world_step(batch: Batch) -> WorldStep | None:
    """A world's people whose sim time moved on (None: none did), each following a teleport, the
    world's view of them refreshed."""
    walking = [person for person in batch.systems if person._ticked(batch.info)]
    if not walking:
        return None
    view, physics = walking[0]._view, walking[0]._physics
    for person in walking:
        person._view = view
        person._follow_teleport()
    changed = view.refresh(tuple(physics.body_names()))
    if changed:
        for person in walking:
            person._near_at = None
    return WorldStep(walking, batch.info.sim_time_ns, Poses(physics), changed)


def _pairs(parts: list[Boxes]) -> tuple[Boxes, Ints]:
    """The rectangles of every person's `parts` in one, and the person each is for."""
    return Boxes.joined(parts), np.repeat(np.arange(len(parts)), [len(part) for part in parts])


def _surroundings(worlds: list[WorldStep], positions: Floats, spans: Floats) -> Surroundings:
    """What each person of `worlds` keeps its distance from: the others of its world (their
    velocities since it last looked), the shadows near it and its world's robots' outlines within
    its reach; each one's robots within the radius and CLOSING_SPEED for an update period are kept
    clear at every step (`_touching`). What each world holds is read world by world, the distances
    for all worlds at once."""
    people = [person for world in worlds for person in world.people]
    blocks: list[tuple[Floats, Floats, Bools]] = []
    statics: list[Boxes] = []
    movables: list[Boxes] = []
    outlines: list[Boxes] = []
    robots: list[str] = []
    first = 0
    for world in worlds:
        view, poses, mine = world.people[0]._view, world.poses, world.people
        bands = [view.band(*person._band) for person in mine]
        placed = {
            key: (band.outlines_at(poses), band.movables_at(poses)) for key, band in {id(b): b for b in bands}.items()
        }
        names = view.people
        others = poses.frames(list(names))[:, :2]
        motions = np.stack([p._motions(names, others, span) for p, span in zip(mine, spans[first : first + len(mine)])])
        seen = np.ones((len(mine), len(names)), bool)
        seen[np.arange(len(mine)), [names.index(person._actor) for person in mine]] = False
        blocks.append((others, motions, seen))
        statics += [person._static_near(band) for person, band in zip(mine, bands)]
        movables += [placed[id(band)][1] for band in bands]
        outlines += [placed[id(band)][0] for band in bands]
        robots += [name for band in bands for name in band.robots]
        first += len(mine)
    static, static_of = _pairs(statics)
    movable, movable_of = _pairs(movables)
    reach = np.array([person._crowd.obstacle_reach for person in people])
    movable = movable.take(keep := movable.within(positions[movable_of], reach[movable_of]))
    outline, outline_of = _pairs(outlines)
    gaps, _ = outline.nearest(positions[outline_of])
    margins = np.array([p._crowd.radius + CLOSING_SPEED * p._period_ns / 1e9 for p in people])[outline_of]
    for person in people:
        person._touching = []
    for pair in np.flatnonzero(gaps < margins):
        people[outline_of[pair]]._touching.append(robots[pair])
    near = outline.within(positions[outline_of], np.array([p._crowd.reach for p in people])[outline_of])
    return Surroundings(
        *block_diagonal(blocks),
        Boxes.joined([static, movable]),
        np.concatenate([static_of, movable_of[keep]]),
        outline.take(near),
        outline_of[near],
    )


def _think(worlds: list[WorldStep]) -> None:
    """The social force on each person of `worlds` from where everyone of its world stands now, each
    velocity steered by it over its update period (semi-implicit Euler), each put back outside
    people and obstacles: every world's people in one pass, each seeing only its own world."""
    people = [person for world in worlds for person in world.people]
    params = Params.of(tuple(person._crowd for person in people))
    spans = np.array([person._span(world.now_ns) for world in worlds for person in world.people])
    positions = np.array([person._position for person in people])
    velocities = (positions - np.array([person._anchor for person in people])) / spans[:, None]
    around = _surroundings(worlds, positions, spans)
    for person in people:
        person._goal = person._route.after(person._goal, person._position, person._crowd.waypoint_tolerance)
    goals = np.array([person._route.points[person._goal] for person in people])
    headings, detoured = detours(params, positions, goals, around.outlines, around.outline_of)
    arriving = np.array([person._route.arriving(person._goal) for person in people]) & ~detoured
    yaws = np.array([person._yaw for person in people])
    accel = accelerations(params, People(positions, velocities, yaws), headings, arriving, around)
    kicks = np.array([p._rng.standard_normal(2) * (p._crowd.noise * math.sqrt(span)) for p, span in zip(people, spans)])
    velocities = steered(params, velocities, accel, spans, kicks)
    positions = kept_clear(params, positions, around)
    for person, position, velocity in zip(people, positions, velocities):
        person._position, person._velocity, person._anchor = position, velocity, position


def _walk(worlds: list[WorldStep]) -> None:
    """Each person of `worlds` on by its velocity over its step, out of the robots it is near,
    turned towards its velocity, and put there."""
    people = [(person, world.poses) for world in worlds for person in world.people]
    params = Params.of(tuple(person._crowd for person, _ in people))
    dts = np.array([person._dt for person, _ in people])
    velocities = np.array([person._velocity for person, _ in people])
    positions = np.array([person._position for person, _ in people]) + velocities * dts[:, None]
    yaws = turned(params, np.array([person._yaw for person, _ in people]), velocities, dts)
    for k, (person, poses) in enumerate(people):
        position = positions[k : k + 1]
        if person._touching:
            footprints = person._view.band(*person._band).footprints_at(person._touching, poses)
            position = outside(params.radius[k : k + 1], position, footprints, np.zeros(len(footprints), np.int64))
        person._position, person._yaw = position[0], float(yaws[k])
        person._put = person._place()
