"""Actors: the one world system that moves every `<actor>` along its script (gz-sim's actors).

A world system (built in, no `<plugin>`): every world gets it, and it takes each actor that enters
the world (at start, or created through world control) from the model events. An actor is a
kinematic body of the physics (simbot.description.actor_scripts: its skin, its ray-visible proxy, its
links), which this system puts, before every physics step, where the script puts it at the step's
sim time (simbot.sim.kit.actor_paths): the actor's frame (its SDF `<pose>`, the trajectory's origin,
as gz-sim's actor Pose component) composed with the trajectory's pose. The motion is a function of
sim time alone, so lockstep runs repeat exactly, and every sensor after the step (lidar rays on
the proxy, cameras drawing the skin, ground truth on `model/<name>/pose`) sees the actor there.

SDF parameters, each actor's own (`<actor>`; read by simbot.description.actor_scripts):

| element | default | what |
| --- | --- | --- |
| `<pose>` | 0 | the actor's frame: the waypoints' origin |
| `<skin><filename>`, `<scale>` | none, 1 | COLLADA drawn by the cameras (bind pose); none: no proxy |
| `<animation name><filename>`, `<scale>`, `<interpolate_x>` | —, 1, false | read and kept; the skin is not animated |
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
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.description.actor_scripts import ActorModel
from simbot.sim.kit.actor_paths import ActorDriver, ScriptPath
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo
from simbot.sim.physics import compose
from simbot.transform import Transform

MOVED_TOLERANCE = 1e-4
"""Metres by which an actor must stand off where it was put to count as moved by someone else (world
control's set_pose): PyBullet's transforms round to single precision, a few µm at tens of metres."""
TURNED_TOLERANCE = 1e-6
"""1 − |q·q'| beyond which it counts as turned (about 3 mrad)."""


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


class Actors:
    """A world system (built in, no `<plugin>`): see the module docstring."""

    name = "Actors"

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        self._actors: dict[str, _Actor] = {}
        self._now_ns = 0

    def model_added(self, event: ModelEvent) -> None:
        """An actor enters: from now on it follows its script, placed at once where the script has it now."""
        if any(isinstance(system, ActorDriver) for system in event.systems):
            return
        for body in event.bodies:
            model = self._physics.model_of(body)
            if isinstance(model, ActorModel):
                frame = self._physics.model_pose(body)
                actor = _Actor(body, ScriptPath.of(model.script), frame, frame)
                self._actors[body] = actor
                self._place(actor, self._now_ns)

    def model_removed(self, event: ModelEvent) -> None:
        for body in event.bodies:
            self._actors.pop(body, None)

    def pre_update(self, info: UpdateInfo) -> None:
        """Every actor where its script puts it at the time this step reaches."""
        self._now_ns = info.sim_time_ns
        for actor in self._actors.values():
            self._follow_teleport(actor)
            self._place(actor, info.sim_time_ns)

    def reset(self, info: UpdateInfo) -> None:
        """Each actor back in its first frame, where its script has it at time zero."""
        self._now_ns = info.sim_time_ns
        for actor in self._actors.values():
            actor.origin, actor.put = actor.initial, None
            self._place(actor, info.sim_time_ns)

    def _place(self, actor: _Actor, now_ns: int) -> None:
        actor.put = compose(actor.origin, actor.path.pose_at(now_ns / 1e9))
        self._physics.set_model_pose(actor.name, actor.put)

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
