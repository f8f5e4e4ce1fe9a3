"""Kinematic fleet mode: robots move by their drives' commands, not by forces, their states held as arrays.

A fleet of a hundred cannot afford a hundred articulated bodies' dynamics and wheel friction at
1 kHz on two cores, nor a thousand robots' per-robot Python at every step. In kinematic mode
(`simbot-server --physics kinematic`, or a world's `<physics type="kinematic">`) nothing is
integrated from forces: PyBullet only detects collisions and casts rays, and the moving bodies'
bases (pose and velocity of each centre of mass) are rows of arrays, which every reader of a base
reads (`bases`: a fleet's IMUs in one query) and PyBullet mirrors. Each step:

1. every drive (DiffDrive, AckermannSteering, MecanumDrive) has said the planar twist of its
   model frame (`drive_base`), after its own clamping and acceleration ramps: all bases with a
   twist move by it at once on the floor plane (heading integrated at the step's midpoint, roll
   and pitch level), their velocities set so that IMUs and velocity readers see the motion; a
   driven base whose twist is zero stands still, at rest;
2. every joint given a velocity (`set_joint_velocity`: wheels, Ackermann's steering servo) turns
   by it, so joint_states and wheel odometry read what the encoders would (held here, and told to
   PyBullet only before something reads PyBullet itself: `sync`);
3. bodies fixed to a moved one (`attach`: a docked trolley) are carried with it;
4. collision detection runs once for the world (the floor planes left out of it once a body is
   driven: the check ignores them); a moved body that now penetrates anything but the
   floor deeper than before goes back to where it was (it stops at the wall or the other robot;
   its wheels keep turning, as against a wall) and the contact is logged once per stop.

Whatever places or sets a body moving from outside (a teleport, world control's set_pose, a reset
to the saved state) says so (`moved`), and its row is read again from PyBullet.

Contacts whose normal is within 45° of vertical are the floor's (a wheel on the ground, a castor).
Free bodies that no robot carries stay where they are. The step is `KINEMATIC_STEP_S` unless the
world's is longer: IMUs and other sensors above 200 Hz are capped at the step rate.

`KinematicWorld` is this mode's `Stepper` (`stepping`, which chooses it when the world asks).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from simbot.description.model import Model, Plane, World
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Bases, Body, read_joint_states, write_joint_positions
from simbot.sim.physics.bullet_transforms import compose, invert
from simbot.sim.physics.wheel_friction import WheelFriction
from simbot.transform import Transform, norm, quaternion_products, rotate_many

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
class Carried:
    """A body fixed to another by `attach`: where it sits in the parent's base frame."""

    parent: int
    child: int
    relative: Transform


POSITION, ORIENTATION, LINEAR, ANGULAR = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13)
"""A row's base: the centre of mass's position and orientation, its linear and angular velocity."""
STATE = slice(0, 13)
TO_POSITION, TO_ORIENTATION = slice(13, 16), slice(16, 20)
"""The model frame in the base frame (`Body.com_to_frame`)."""
TWIST, DEPTH, DRIVEN = slice(20, 23), 23, 24
"""The drive's twist (forward, lateral, turn of the model frame), how deep the body penetrated an
obstacle at its last accepted pose (0: clear), and 1 once a drive has named it."""
WIDTH = 25
Floats = npt.NDArray[np.float64]


@dataclass
class KinematicWorld:
    """The kinematic stepping of one PyBullet world (see the module docstring), a `stepping.Stepper`."""

    client: int
    dt: float
    """The step (the world's step size, s)."""
    rows: Floats = field(default_factory=lambda: np.zeros((0, WIDTH)))
    """A row per moving body (in the order they entered): its base, where its model frame sits, its drive."""
    ids: list[int] = field(default_factory=list)
    """Each row's PyBullet body."""
    _row: dict[int, int] = field(default_factory=dict)
    blocked_by: dict[int, str] = field(default_factory=dict)
    """The body each blocked body last stopped at."""
    joints: dict[int, dict[int, float]] = field(default_factory=dict)
    """Per body: joint index → the velocity it turns at."""
    positions: dict[int, dict[int, float]] = field(default_factory=dict)
    """Per body: joint index → where each joint of `joints` stands, read once from PyBullet and then
    turned here; PyBullet is told at `sync`."""
    _unsynced: set[int] = field(default_factory=set)
    """Bodies whose joints turned since PyBullet was last told."""
    carried: dict[int, Carried] = field(default_factory=dict)
    """Per constraint made by `attach`."""
    _parked: set[int] = field(default_factory=set)
    """Bodies whose joints stand still and read so."""
    _floors: dict[int, bool] = field(default_factory=dict)
    """Whether each body looked at is a floor plane."""

    def add(self, body: Body, wheels: WheelFriction | None) -> None:
        """A row for a body that can move, read from PyBullet; it is stepped once a drive or a joint
        command names it (wheels turn, never roll)."""
        if body.model.static:
            return
        row = np.zeros(WIDTH)
        row[TO_POSITION], row[TO_ORIENTATION] = body.com_to_frame
        self._row[body.id] = len(self.ids)
        self.ids.append(body.id)
        self.rows = np.vstack([self.rows, row])
        self.moved([body.id])

    def forget(self, body: int) -> None:
        """A body left the world."""
        if (row := self._row.pop(body, None)) is not None:
            self.rows = np.delete(self.rows, row, axis=0)
            del self.ids[row]
            self._row = {id_: k for k, id_ in enumerate(self.ids)}
        self.blocked_by.pop(body, None)
        self._floors.pop(body, None)
        self.joints.pop(body, None)
        self.positions.pop(body, None)
        self._unsynced.discard(body)
        self._parked.discard(body)
        self.carried = {c: k for c, k in self.carried.items() if body not in (k.parent, k.child)}

    def moved(self, ids: Sequence[int]) -> None:
        """Bodies placed or set moving from outside the stepping: their rows read again from PyBullet."""
        rows = [self._row[body] for body in ids if body in self._row]
        if rows:
            bases = Bases.read(self.client, [self.ids[row] for row in rows])
            self.rows[rows, STATE] = np.hstack(bases)

    def restored(self) -> None:
        """The world came back from a saved state (a reset): every row and joint read again."""
        self.moved(self.ids)
        self.positions.clear()
        self._unsynced.clear()
        self._parked.clear()

    def sync(self) -> None:
        """PyBullet's joints where they turned to: before anything reads them there (a link's pose,
        a cast, a contact, a saved state), not at every step (20 µs a tug)."""
        for body in self._unsynced:
            positions, velocities = self.positions[body], self.joints[body]
            joints = list(positions)
            write_joint_positions(
                self.client, body, joints, [positions[j] for j in joints], [velocities[j] for j in joints]
            )
        self._unsynced.clear()

    def joint_states(self, body: int, joints: Sequence[int]) -> list[tuple[float, float, float]]:
        """(position, velocity, effort) of each joint: a turning joint's from here (no effort: no
        force is computed), any other's from PyBullet."""
        turned, velocities = self.positions.get(body, {}), self.joints.get(body, {})
        try:
            return [(turned[joint], velocities[joint], 0.0) for joint in joints]
        except KeyError:  # one not turning here
            self.sync()
            return read_joint_states(self.client, body, joints)

    def set_joint_positions(self, body: int, joints: Sequence[int], values: Sequence[float]) -> None:
        """Joints put at `values` at rest (an actor's legs), here and in PyBullet (the others turned
        since the last `sync` stay to be told then)."""
        turned = self.positions.get(body, {})
        for joint, value in zip(joints, values):
            if joint in turned:
                turned[joint] = value
        write_joint_positions(self.client, body, joints, values)

    def bases(self, ids: Sequence[int]) -> Bases:
        """The bases of bodies `ids`: a moving body's from its row, a static one's from PyBullet."""
        rows = [self._row.get(body, -1) for body in ids]
        if -1 in rows:
            return Bases.read(self.client, ids)
        state = self.rows[rows]
        return Bases(state[:, POSITION], state[:, ORIENTATION], state[:, LINEAR], state[:, ANGULAR])

    def drive(self, body: Body, others: Iterable[Body], forward: float, lateral: float, turn: float) -> None:
        """The base's twist from now on; the first one sets the body down on the floor (`others` below
        it, read only then: a drive says its twist every step it ramps)."""
        row = self.rows[self._row[body.id]]
        if not row[DRIVEN]:
            others = list(others)
            self._settle(body.id, others)
            self._off_the_floor(body.id, others)
            row[DRIVEN] = 1.0
        row[TWIST] = (forward, lateral, turn)

    def _settle(self, body: int, others: Iterable[Body]) -> None:
        """Lowers (or lifts) `body` until it touches what supports it: nothing falls in kinematic mode,
        and a robot spawned above the floor would carry its lidars too high."""
        near = self._near(body)
        gaps = [
            c[8]
            for other in others
            if other.id != body and other.id in near
            for c in pb.getClosestPoints(body, other.id, SETTLE_SEARCH_M, physicsClientId=self.client)
            if abs(c[7][2]) >= FLOOR_NORMAL_Z
        ]
        if gaps:
            (x, y, z), quat = pb.getBasePositionAndOrientation(body, physicsClientId=self.client)
            pb.resetBasePositionAndOrientation(body, (x, y, z - min(gaps)), quat, physicsClientId=self.client)
            self.moved([body])

    def _near(self, body: int) -> set[int]:
        """The bodies whose bounds come within SETTLE_SEARCH_M of `body`'s (PyBullet's broadphase):
        the only ones a closest-point query can find, so that a thousand tugs' first drives do not
        ask each of the others."""
        links = range(-1, pb.getNumJoints(body, physicsClientId=self.client))
        bounds = np.array([pb.getAABB(body, link, physicsClientId=self.client) for link in links])
        low, high = bounds[:, 0].min(axis=0) - SETTLE_SEARCH_M, bounds[:, 1].max(axis=0) + SETTLE_SEARCH_M
        found = pb.getOverlappingObjects(low.tolist(), high.tolist(), physicsClientId=self.client) or ()
        return {other for other, _ in found}

    def _off_the_floor(self, body: int, others: Iterable[Body]) -> None:
        """No contacts between `body` and the floor planes from now on: the check ignores them (their
        normals are vertical), and PyBullet made them for every wheel and castor at every step
        (measured: 40 µs a moving tug a step of the world's collision detection, 26 µs of its
        contact query, 300 tugs driven)."""
        links = [-1, *range(pb.getNumJoints(body, physicsClientId=self.client))]
        for floor in (other for other in others if self._floor(other)):
            for link in links:
                pb.setCollisionFilterPair(floor.id, body, -1, link, 0, physicsClientId=self.client)

    def _floor(self, body: Body) -> bool:
        """Whether `body` is a floor plane (`_floor_plane`), looked at once a body."""
        if body.id not in self._floors:
            self._floors[body.id] = _floor_plane(body.model)
        return self._floors[body.id]

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

    def step(self, bodies: dict[str, Body]) -> None:
        """One step of every driven body, turning joint and carried body (module docstring)."""
        driven = self.rows[:, DRIVEN] > 0
        twisting = self.rows[:, TWIST].any(axis=1)
        moving = np.flatnonzero(driven & twisting)
        self._stop(np.flatnonzero(driven & ~twisting & self.rows[:, LINEAR.start : ANGULAR.stop].any(axis=1)))
        before = self.rows[moving, STATE].copy()
        if len(moving):
            self._move(moving)
        for body, velocities in self.joints.items():
            self._turn(body, velocities, self.dt)
        for carried in self.carried.values():
            pose = compose(self._base(carried.parent), carried.relative)
            pb.resetBasePositionAndOrientation(carried.child, *pose, physicsClientId=self.client)
            if carried.child in self._row:
                self.rows[self._row[carried.child], POSITION.start : ORIENTATION.stop] = (*pose[0], *pose[1])
        if not len(moving):
            return
        pb.performCollisionDetection(physicsClientId=self.client)
        names = {body.id: name for name, body in bodies.items()}
        for row, old in zip(moving.tolist(), before):
            self._check(row, old, names)

    def _base(self, body: int) -> Transform:
        return Transform.of(*pb.getBasePositionAndOrientation(body, physicsClientId=self.client))

    def _move(self, rows: npt.NDArray[np.intp]) -> None:
        """Moves the model frames of `rows` by their twists over dt, level on the floor, at once."""
        state, dt = self.rows[rows], self.dt
        to_position, to_orientation = state[:, TO_POSITION], state[:, TO_ORIENTATION]
        frame = state[:, POSITION] + rotate_many(state[:, ORIENTATION], to_position)
        x, y, z, w = quaternion_products(state[:, ORIENTATION], to_orientation).T
        yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        forward, lateral, turn = state[:, TWIST].T
        mid, new_yaw = yaw + turn * dt / 2, yaw + turn * dt
        c, s = np.cos(mid), np.sin(mid)
        frame[:, 0] += (c * forward - s * lateral) * dt
        frame[:, 1] += (s * forward + c * lateral) * dt
        heading = np.zeros((len(rows), 4))
        heading[:, 2], heading[:, 3] = np.sin(new_yaw / 2), np.cos(new_yaw / 2)
        orientation = quaternion_products(heading, to_orientation * (-1.0, -1.0, -1.0, 1.0))
        position = frame - rotate_many(orientation, to_position)
        cn, sn = np.cos(new_yaw), np.sin(new_yaw)
        rx, ry = position[:, 0] - frame[:, 0], position[:, 1] - frame[:, 1]
        linear = np.zeros((len(rows), 3))
        linear[:, 0] = cn * forward - sn * lateral - turn * ry  # v + ω × r
        linear[:, 1] = sn * forward + cn * lateral + turn * rx
        angular = np.zeros((len(rows), 3))
        angular[:, 2] = turn
        self.rows[rows, STATE] = np.hstack([position, orientation, linear, angular])
        self._mirror(rows)

    def _stop(self, rows: npt.NDArray[np.intp]) -> None:
        """Driven bodies whose twist fell to zero: at rest where they stand."""
        if len(rows):
            self.rows[rows, LINEAR.start : ANGULAR.stop] = 0.0
            self._mirror(rows)

    def _mirror(self, rows: npt.NDArray[np.intp]) -> None:
        """PyBullet's bodies where the rows have them: what it collides and casts against."""
        for row, state in zip(rows.tolist(), self.rows[rows, STATE].tolist()):
            body = self.ids[row]
            pb.resetBasePositionAndOrientation(body, state[0:3], state[3:7], physicsClientId=self.client)
            pb.resetBaseVelocity(body, state[7:10], state[10:13], physicsClientId=self.client)

    def _turn(self, body: int, velocities: dict[int, float], dt: float) -> None:
        """Each joint on by its velocity over dt (PyBullet told at `sync`); a parked robot's cost
        nothing once its joints stand still."""
        moving = any(velocities.values())
        if not moving and body in self._parked:
            return
        if moving:
            self._parked.discard(body)
        else:
            self._parked.add(body)
        positions = self.positions.setdefault(body, {})
        if unread := [joint for joint in velocities if joint not in positions]:
            positions.update(
                (joint, state[0]) for joint, state in zip(unread, read_joint_states(self.client, body, unread))
            )
        for joint, velocity in velocities.items():
            positions[joint] += velocity * dt
        self._unsynced.add(body)

    def _check(self, row: int, old: Floats, names: dict[int, str]) -> None:
        """Back to `old` (its base before the move), at rest, if the move sank the body deeper into
        something than it was."""
        body = self.ids[row]
        depth, other = 0.0, -1
        for c in pb.getContactPoints(bodyA=body, physicsClientId=self.client):
            if c[8] < -depth and abs(c[7][2]) < FLOOR_NORMAL_Z and not self._riding(body, c[2]):
                depth, other = -c[8], c[2]
        if depth <= self.rows[row, DEPTH] + PENETRATION_SLOP_M:
            self.rows[row, DEPTH] = depth
            self.blocked_by.pop(body, None)
            return
        self.rows[row, STATE] = old
        self.rows[row, LINEAR.start : ANGULAR.stop] = 0.0
        self._mirror(np.array([row]))
        blocker = names.get(other, str(other))
        if self.blocked_by.get(body) != blocker:
            log.info("%s stopped by contact with %s", names.get(body, body), blocker)
        self.blocked_by[body] = blocker

    def _riding(self, body: int, other: int) -> bool:
        """Whether `other` is carried by `body` or carries it (a docked trolley touches its tug)."""
        return any({carried.parent, carried.child} == {body, other} for carried in self.carried.values())


def _floor_plane(model: Model) -> bool:
    """Whether `model` is a static floor: a plane facing up, all it collides with, its frames level."""
    level = [model.pose, *(link.pose for link in model.links)]
    level += [collision.pose for link in model.links for collision in link.collisions]
    planes = [collision.geometry for link in model.links for collision in link.collisions]
    return (
        model.static
        and bool(planes)
        and all(isinstance(plane, Plane) and plane.normal[2] >= FLOOR_NORMAL_Z * norm(plane.normal) for plane in planes)
        and all(abs(pose.rpy[0]) < 1e-9 and abs(pose.rpy[1]) < 1e-9 for pose in level)
    )
