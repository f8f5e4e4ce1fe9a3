"""Actors: the one world system that moves every `<actor>` along its script (gz-sim's actors).

A world system (built in, no `<plugin>`): every world gets it, and it takes each actor that enters
the world (at start, or created through world control) from the model events. An actor is a
kinematic body of the physics (simbot.description.actor_scripts: its skin, its ray-visible proxy, its
links), which this system puts, before every physics step, where the script puts it at the step's
sim time (simbot.description.actor_paths): the actor's frame (its SDF `<pose>`, the trajectory's origin,
as gz-sim's actor Pose component) composed with the trajectory's pose. The motion is a function of
sim time alone, so lockstep runs repeat exactly, and every sensor after the step (lidar rays on
the proxy, cameras drawing the skin, ground truth on `model/<name>/pose`) sees the actor there.

SDF parameters, each actor's own (`<actor>`; read by simbot.description.actor_scripts):

| element | default | what |
| --- | --- | --- |
| `<pose>` | 0 | the actor's frame: the waypoints' origin |
| `<skin><filename>`, `<scale>` | none, 1 | COLLADA drawn by the cameras (bind pose); none: no proxy |
| `<animation name><filename>`, `<scale>`, `<interpolate_x>` | —, 1, false | the clip a trajectory of that `type` plays (else the first); `interpolate_x`: its phase follows the distance walked |
| `<script><loop>` | true | repeat the trajectories |
| `<script><delay_start>` | 0 s | stand at the start this long |
| `<script><auto_start>` | true | false: stand at the start (gz-sim ignores it; SDF says the script waits) |
| `<trajectory id type tension>` | —, —, 0 | played in file order; `tension` of the position spline |
| `<waypoint><time>`, `<pose>` | required | in time order, the pose in the actor's frame |

World control acts on actors as on models: `set_pose` moves the actor's frame (the trajectory's
origin, as Gazebo's set_pose sets an actor's Pose component), so it walks its script from there;
`reset` returns it to its SDF frame at time zero; `remove` and `create` (an SDF whose root is an
`<actor>`) take it out and put one in. An actor whose own systems include one that moves it
(`ActorDriver`: FollowActor) is left to that system, as a TrajectoryPose overrides the script in gz-sim.

An actor whose skin has a skeleton and animations (simbot.description.actor_legs) has its legs
posed here too, whoever moves it, every LEGS_PERIOD_NS of sim time (100 Hz: the first step at or
after each multiple of it, as a sensor's own rate; at once when it enters and on reset): the clip's
time from the distance its frame has moved in the floor plane (summed at each posing; a jump over
MAX_STRIDE_M, a teleport, is not walked) or from the sim time, the clip its trajectory's `type`
names; the legs' joints and the `body_skin_*` joints that the cameras pose the skin from are set
to it. Between posings the legs hold their pose on the moving frame. Posing every step cost
most of an animated worker's time in the step (benchmarks/bench_actors.py, docs/actors.md); a
lidar at a rate whose period is a multiple of 10 ms (the tug's 10 Hz) reads legs posed for its
own instant, and a camera at 30 Hz draws the skin and legs as they were up to 10 ms earlier
(a foot moves 2–4 cm in that time at walking speed).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simbot.description.actor_legs import GAIT_SAMPLES, ActorRig
from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import BODY, ActorModel, SkinnedMesh
from simbot.description.skeleton_poses import ClipFile, load_rig
from simbot.sim.kit.actor_driver import ActorDriver
from simbot.sim.kit.rates import Every
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo
from simbot.sim.physics import compose
from simbot.transform import Transform

MOVED_TOLERANCE = 1e-4
"""Metres by which an actor must stand off where it was put to count as moved by someone else (world
control's set_pose): PyBullet's transforms round to single precision, a few µm at tens of metres."""
TURNED_TOLERANCE = 1e-6
"""1 − |q·q'| beyond which it counts as turned (about 3 mrad)."""
MAX_STRIDE_M = 1.0
"""Metres an actor's frame may move between two posings of its legs and count as walked (more: it
was put there)."""
LEGS_PERIOD_NS = 10_000_000
"""Sim time between posings of animated legs (see the module docstring): a multiple of it is the
instant of every lidar tick at 10, 20, 25, 50 or 100 Hz."""


@dataclass
class _Gait:
    """An animated actor's leg joint positions tabled over each clip, and the distance it has walked."""

    rig: ActorRig
    names: tuple[str, ...]
    tables: tuple[np.ndarray, ...]
    """Per clip: (GAIT_SAMPLES + 1) × joints, at evenly spaced clip times."""
    animations: dict[str, int]
    distance: float = 0.0
    last: tuple[float, float] | None = None

    @staticmethod
    def of(model: ActorModel) -> _Gait | None:
        skin = next((v.geometry for v in model.link(BODY).visuals if isinstance(v.geometry, SkinnedMesh)), None)
        if skin is None or skin.path is None or not skin.animations:  # none, or drawn in its bind pose
            return None
        rig, names, tables = _tabled(skin.path, skin.animations, skin.scale[0])
        return _Gait(rig, names, tables, {a.name: i for i, a in enumerate(model.animations)})

    def walked(self, x: float, y: float) -> None:
        if self.last is not None:
            step = math.hypot(x - self.last[0], y - self.last[1])
            self.distance += step if step <= MAX_STRIDE_M else 0.0
        self.last = (x, y)

    def positions(self, animation: int, sim_time: float) -> dict[str, float]:
        """The joints at the clip's time (linear between the table's rows), the clip's time exact."""
        time = self.rig.rig.clip_time(animation, sim_time, self.distance)
        duration = self.rig.rig.clips[animation].duration
        table = self.tables[animation]
        at = time / duration * GAIT_SAMPLES if duration > 0 else 0.0
        k = min(int(at), GAIT_SAMPLES - 1)
        row = table[k] + (table[k + 1] - table[k]) * (at - k)
        out = dict(zip(self.names, row.tolist(), strict=True))
        out[self.names[0]] = time
        return out


@functools.lru_cache(maxsize=64)
def _tabled(
    skin: Path, clips: tuple[ClipFile, ...], scale: float
) -> tuple[ActorRig, tuple[str, ...], tuple[np.ndarray, ...]]:
    """A skin's legs tabled over each clip, once for each skin, clips and scale (read only): an
    actor that enters again (a seeded reset's people) finds its table made."""
    rig = ActorRig.of(load_rig(skin, clips), scale)
    tables = []
    for index, clip in enumerate(rig.rig.clips):
        rows = [rig.positions(index, clip.duration * k / GAIT_SAMPLES) for k in range(GAIT_SAMPLES + 1)]
        tables.append(np.array([list(row.values()) for row in rows]))
    return rig, tuple(rig.positions(0, 0.0)), tuple(tables)


@dataclass
class _Actor:
    """One actor in the world: its script, its frame, and where it was last put."""

    name: str
    path: ScriptPath
    initial: Transform
    """Its frame as the world started (or as created): where reset puts it back."""
    origin: Transform
    put: Transform | None = None
    """The world pose it was last put at."""
    scripted: bool = True
    """False: another system moves it (an `ActorDriver`); its legs are posed here all the same."""
    gait: _Gait | None = field(default=None, repr=False)
    """Its legs' posing, where its skin is animated."""


class Actors:
    """A world system (built in, no `<plugin>`): see the module docstring."""

    name = "Actors"

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        self._actors: dict[str, _Actor] = {}
        self._now_ns = 0
        self._legs = Every(LEGS_PERIOD_NS)

    def model_added(self, event: ModelEvent) -> None:
        """An actor enters: from now on it follows its script, placed at once where the script has it now."""
        driven = any(isinstance(system, ActorDriver) for system in event.systems)
        for body in event.bodies:
            model = self._physics.model_of(body)
            if not isinstance(model, ActorModel):
                continue
            gait = _Gait.of(model) if model.animations else None
            if gait is not None or not driven:
                frame = self._physics.model_pose(body)
                actor = _Actor(body, ScriptPath.of(model.script), frame, frame, scripted=not driven, gait=gait)
                self._actors[body] = actor
                self._update(actor, self._now_ns, legs=True)

    def model_removed(self, event: ModelEvent) -> None:
        for body in event.bodies:
            self._actors.pop(body, None)

    def pre_update(self, info: UpdateInfo) -> None:
        """Every actor where its script puts it at the time this step reaches."""
        self._now_ns = info.sim_time_ns
        legs = self._legs.due(info.sim_time_ns)
        for actor in self._actors.values():
            if actor.scripted:
                self._follow_teleport(actor)
            self._update(actor, info.sim_time_ns, legs)

    def reset(self, info: UpdateInfo) -> None:
        """Each actor back in its first frame, where its script has it at time zero."""
        self._now_ns = info.sim_time_ns
        self._legs.restart()
        for actor in self._actors.values():
            actor.origin, actor.put = actor.initial, None
            if actor.gait is not None:
                actor.gait.distance, actor.gait.last = 0.0, None
            self._update(actor, info.sim_time_ns, legs=True)

    def _update(self, actor: _Actor, now_ns: int, legs: bool) -> None:
        """A scripted actor where its script has it; an animated one's legs, where `legs`, as its gait has them."""
        if actor.scripted:
            actor.put = compose(actor.origin, actor.path.pose_at(now_ns / 1e9))
            self._physics.set_model_pose(actor.name, actor.put)
        if legs and actor.gait is not None:
            self._pose_legs(actor, actor.gait, now_ns)

    def _pose_legs(self, actor: _Actor, gait: _Gait, now_ns: int) -> None:
        """The legs' joints at the clip's time: from the distance walked since the last posing, or the sim time."""
        x, y, _ = (
            actor.put if actor.scripted and actor.put is not None else self._physics.model_pose(actor.name)
        ).position
        gait.walked(x, y)
        playing = actor.path.trajectory_at(now_ns / 1e9) if actor.scripted else None
        kind = actor.path.script.trajectories[playing].type if playing is not None else ""
        self._physics.set_joint_positions(actor.name, gait.positions(gait.animations.get(kind, 0), now_ns / 1e9))

    def _follow_teleport(self, actor: _Actor) -> None:
        """An actor put elsewhere since the last step (world control's set_pose) has its frame there:
        as Gazebo's set_pose sets an actor's Pose component, the script runs from the new origin."""
        if actor.put is not None and not _near(self._physics.model_pose(actor.name), actor.put):
            actor.origin = self._physics.model_pose(actor.name)


def _near(a: Transform, b: Transform) -> bool:
    """Whether two poses are one (a quaternion and its negation are one rotation)."""
    (ax, ay, az), (bx, by, bz) = a.position, b.position
    if abs(ax - bx) > MOVED_TOLERANCE or abs(ay - by) > MOVED_TOLERANCE or abs(az - bz) > MOVED_TOLERANCE:
        return False
    (qx, qy, qz, qw), (rx, ry, rz, rw) = a.orientation, b.orientation
    return 1.0 - abs(qx * rx + qy * ry + qz * rz + qw * rw) <= TURNED_TOLERANCE
