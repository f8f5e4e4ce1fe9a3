"""Kinematic fleet mode: robots move by their drives' commands, not by forces.

A fleet of a hundred cannot afford a hundred articulated bodies' dynamics and wheel friction at
1 kHz on two cores. In kinematic mode (`simbot-server --physics kinematic`, or a world's
`<physics type="kinematic">`) nothing is integrated from forces: PyBullet only detects collisions
and casts rays. Each step:

1. every drive (DiffDrive, AckermannSteering, MecanumDrive) has said the planar twist of its
   model frame (`drive_base`), after its own clamping and acceleration ramps: the base moves by
   it on the floor plane (heading integrated at the step's midpoint, roll and pitch level), and
   its velocity is set so that IMUs and velocity readers see the motion;
2. every joint given a velocity (`set_joint_velocity`: wheels, Ackermann's steering servo) turns
   by it, so joint_states and wheel odometry read what the encoders would;
3. bodies fixed to a moved one (`attach`: a docked trolley) are carried with it;
4. collision detection runs once for the world; a moved body that now penetrates anything but the
   floor deeper than before goes back to where it was (it stops at the wall or the other robot;
   its wheels keep turning, as against a wall) and the contact is logged once per stop.

Contacts whose normal is within 45° of vertical are the floor's (a wheel on the ground, a castor).
Free bodies that no robot carries stay where they are. The step is `KINEMATIC_STEP_S` unless the
world's is longer: IMUs and other sensors above 200 Hz are capped at the step rate.

`KinematicStepper` is this mode's `Stepper` (`stepping`, which chooses it when the world asks).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

from simbot.description.model import World
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Body
from simbot.sim.physics.bullet_transforms import compose, invert
from simbot.sim.physics.wheel_friction import WheelFriction
from simbot.transform import Transform

log = logging.getLogger(__name__)

KINEMATIC = "kinematic"
"""The `<physics type>` and `--physics` value that asks for this mode."""
KINEMATIC_STEP_S = 0.005
"""200 Hz: a drive's command and a robot's pose advance at this rate (the world's step where longer)."""
FLOOR_NORMAL_Z = math.cos(math.radians(45))
"""A contact whose normal is this close to vertical supports a body: it never stops one."""
SETTLE_SEARCH_M = 0.5
"""How far below a robot its floor is looked for when it is first driven."""
PENETRATION_SLOP_M = 1e-4
"""Depth a moved body may sink into an obstacle beyond what it already did (numerical noise)."""


def kinematic(world: World) -> World:
    """`world` stepped kinematically, at KINEMATIC_STEP_S or its own step where longer."""
    step = max(world.physics.max_step_size, KINEMATIC_STEP_S)
    return replace(world, physics=replace(world.physics, type=KINEMATIC, max_step_size=step))


@dataclass
class Driven:
    """A robot's base as its drive commands it, and whether it stands blocked."""

    twist: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """forward, lateral (m/s) and turn rate (rad/s) of the model frame."""
    depth: float = 0.0
    """How deep it penetrated an obstacle at its last accepted pose (0: clear)."""
    blocked_by: str | None = None


@dataclass
class Carried:
    """A body fixed to another by `attach`: where it sits in the parent's base frame."""

    parent: int
    child: int
    relative: Transform


@dataclass
class KinematicStepper:
    """The kinematic stepping of one PyBullet world (see the module docstring), a `stepping.Stepper`."""

    client: int
    dt: float
    """The step (the world's step size, s)."""
    driven: dict[int, Driven] = field(default_factory=dict)
    joints: dict[int, dict[int, float]] = field(default_factory=dict)
    """Per body: joint index → the velocity it turns at."""
    carried: dict[int, Carried] = field(default_factory=dict)
    """Per constraint made by `attach`."""
    _parked: set[int] = field(default_factory=set)
    """Bodies whose joints stand still and read so."""

    def drive(self, body: Body, others: Iterable[Body], forward: float, lateral: float, turn: float) -> None:
        """The base's twist from now on; the first one sets the body down on the floor (`others` below
        it, read only then: a drive says its twist every step it ramps)."""
        if body.id not in self.driven:
            self._settle(body.id, others)
        self.driven.setdefault(body.id, Driven()).twist = (forward, lateral, turn)

    def _settle(self, body: int, others: Iterable[Body]) -> None:
        """Lowers (or lifts) `body` until it touches what supports it: nothing falls in kinematic mode,
        and a robot spawned above the floor would carry its lidars too high."""
        gaps = [
            c[8]
            for other in others
            if other.id != body
            for c in pb.getClosestPoints(body, other.id, SETTLE_SEARCH_M, physicsClientId=self.client)
            if abs(c[7][2]) >= FLOOR_NORMAL_Z
        ]
        if gaps:
            (x, y, z), quat = pb.getBasePositionAndOrientation(body, physicsClientId=self.client)
            pb.resetBasePositionAndOrientation(body, (x, y, z - min(gaps)), quat, physicsClientId=self.client)

    def joint_velocity(self, body: int, joint: int, velocity: float, max_effort: float) -> None:
        """The joint turns at `velocity` from now on, whatever `max_effort`: no force is computed."""
        self.joints.setdefault(body, {})[joint] = velocity

    def carry(self, constraint: int, parent: int, child: int) -> None:
        """`child` rides with `parent` from now on, as it sits now (base frames)."""
        relative = compose(invert(self._base(parent)), self._base(child))
        self.carried[constraint] = Carried(parent, child, relative)

    def release(self, constraint: int) -> None:
        """The joint `carry` followed is gone: its child stays where it is."""
        self.carried.pop(constraint, None)

    def add(self, body: int, wheels: WheelFriction | None) -> None:
        """Nothing: a body is stepped once a drive or a joint command names it; wheels turn, never roll."""

    def forget(self, body: int) -> None:
        """A body left the world."""
        self.driven.pop(body, None)
        self.joints.pop(body, None)
        self._parked.discard(body)
        self.carried = {c: k for c, k in self.carried.items() if body not in (k.parent, k.child)}

    def step(self, bodies: dict[str, Body]) -> None:
        """One step of every driven body, turning joint and carried body (module docstring)."""
        by_id = {body.id: body for body in bodies.values()}
        before = {
            body: self._move(by_id[body], driven.twist, self.dt)
            for body, driven in self.driven.items()
            if body in by_id and driven.twist != (0.0, 0.0, 0.0)
        }
        for body, velocities in self.joints.items():
            self._turn(body, velocities, self.dt)
        for carried in self.carried.values():
            pb.resetBasePositionAndOrientation(
                carried.child, *compose(self._base(carried.parent), carried.relative), physicsClientId=self.client
            )
        if not before:
            return
        pb.performCollisionDetection(physicsClientId=self.client)
        names = {body.id: name for name, body in bodies.items()}
        for body, old in before.items():
            self._check(body, old, names)

    def _base(self, body: int) -> Transform:
        return Transform.of(*pb.getBasePositionAndOrientation(body, physicsClientId=self.client))

    def _move(self, body: Body, twist: tuple[float, float, float], dt: float) -> Transform:
        """Moves the model frame by the twist over dt, level on the floor; returns the base's old pose."""
        com = self._base(body.id)
        (x, y, z), quat = compose(com, body.com_to_frame)
        forward, lateral, turn = twist
        yaw = math.atan2(2 * (quat[3] * quat[2] + quat[0] * quat[1]), 1 - 2 * (quat[1] ** 2 + quat[2] ** 2))
        mid, new_yaw = yaw + turn * dt / 2, yaw + turn * dt
        c, s = math.cos(mid), math.sin(mid)
        frame = Transform(
            (x + (c * forward - s * lateral) * dt, y + (s * forward + c * lateral) * dt, z),
            (0.0, 0.0, math.sin(new_yaw / 2), math.cos(new_yaw / 2)),
        )
        new_com = compose(frame, invert(body.com_to_frame))
        cn, sn = math.cos(new_yaw), math.sin(new_yaw)
        linear = (cn * forward - sn * lateral, sn * forward + cn * lateral, 0.0)
        rx, ry = new_com[0][0] - frame[0][0], new_com[0][1] - frame[0][1]
        com_velocity = (linear[0] - turn * ry, linear[1] + turn * rx, 0.0)  # v + ω × r
        pb.resetBasePositionAndOrientation(body.id, *new_com, physicsClientId=self.client)
        pb.resetBaseVelocity(body.id, com_velocity, (0.0, 0.0, turn), physicsClientId=self.client)
        return com

    def _turn(self, body: int, velocities: dict[int, float], dt: float) -> None:
        """Each joint on by its velocity over dt, in one call a body; a parked robot's cost nothing
        once its joints read their zero velocities."""
        moving = any(velocities.values())
        if not moving and body in self._parked:
            return
        if moving:
            self._parked.discard(body)
        else:
            self._parked.add(body)
        joints = list(velocities)
        states = pb.getJointStates(body, joints, physicsClientId=self.client)
        speeds = [[velocities[joint]] for joint in joints]
        positions = [[state[0] + speed[0] * dt] for state, speed in zip(states, speeds)]
        pb.resetJointStatesMultiDof(body, joints, positions, speeds, physicsClientId=self.client)

    def _check(self, body: int, old: Transform, names: dict[int, str]) -> None:
        """Back to `old` if the move sank the body deeper into something than it was."""
        driven = self.driven[body]
        depth, other = 0.0, -1
        for c in pb.getContactPoints(bodyA=body, physicsClientId=self.client):
            if c[8] < -depth and abs(c[7][2]) < FLOOR_NORMAL_Z and not self._riding(body, c[2]):
                depth, other = -c[8], c[2]
        if depth <= driven.depth + PENETRATION_SLOP_M:
            driven.depth, driven.blocked_by = depth, None
            return
        pb.resetBasePositionAndOrientation(body, *old, physicsClientId=self.client)
        pb.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), physicsClientId=self.client)
        blocker = names.get(other, str(other))
        if driven.blocked_by != blocker:
            log.info("%s stopped by contact with %s", names.get(body, body), blocker)
        driven.blocked_by = blocker

    def _riding(self, body: int, other: int) -> bool:
        """Whether `other` is carried by `body` or carries it (a docked trolley touches its tug)."""
        return any({carried.parent, carried.child} == {body, other} for carried in self.carried.values())
