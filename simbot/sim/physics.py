"""The PyBullet world: the one module that loads bodies into PyBullet and steps it.

Systems never see body or link indices: they name a model, a link or a joint, and this module
maps names to PyBullet's indices. Poses are always those of the SDF frames (PyBullet reports a
body's centre of mass; the offset is undone here once).
"""

from __future__ import annotations

import itertools
import logging
import math
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import wraps
from pathlib import Path
from typing import Any, Concatenate, ParamSpec, TypeVar

import numpy as np
import numpy.typing as npt

from simbot.description import model_to_urdf
from simbot.description.generated_meshes import heightmap_heights
from simbot.description.model import Collision, Heightmap, Joint, Link, Model, Sphere, World
from simbot.description.poses import IDENTITY, Pose
from simbot.description.urdf_writer import joint_trees, link_frame, urdf_root
from simbot.sim.bullet import pb, quiet
from simbot.sim.wheel_friction import TYRE_STIFFNESS, Wheel, WheelFriction

logger = logging.getLogger(__name__)

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Transform = tuple[Vec3, Quat]

SDF_DEFAULT_MU = 1.0
"""SDF's friction default. PyBullet multiplies two surfaces' coefficients, so with 1.0 on every
surface that states none, a pair where one side states μ behaves as ODE's min(μ1, μ2)."""

FIXED_CONSTRAINT_FORCE = 1e6
"""Newtons a detachable joint may exert: rigid for anything the tug can pull."""

RAY_GROUP_BITS = range(10, 31)
"""Collision-group bits that tell robots apart for rays. PyBullet's own groups are 1 (dynamic) and
2 (static), Bullet's up to 32 (bit 5); a body in groups of these bits alone, with mask −1, still
collides with all."""


def ray_groups() -> Iterator[int]:
    """Each robot's ray group: two bits of RAY_GROUP_BITS, a pair no other robot has (210 robots).
    No pair holds another, so a ray mask that clears one robot's bits keeps a bit of every other's:
    a sensor is blind to its own robot and sees every other one. As cheap as dropping hits on the own
    body from rayTestBatch's results (measured: the same for 720 rays among ten tugs) and exact, where
    a dropped hit would hide whatever lies beyond it."""
    return ((1 << a) | (1 << b) for a, b in itertools.combinations(RAY_GROUP_BITS, 2))


class PhysicsReadOnly(RuntimeError):
    """A system changed the world where it may only read it (in post_update, as Gazebo's PostUpdate)."""


P = ParamSpec("P")
R = TypeVar("R")


def _changes_world(method: Callable[Concatenate[Physics, P], R]) -> Callable[Concatenate[Physics, P], R]:
    """Marks a method that changes the world: refused while the physics is read-only."""

    @wraps(method)
    def guarded(self: Physics, *args: P.args, **kwargs: P.kwargs) -> R:
        if self.read_only:
            raise PhysicsReadOnly(f"Physics.{method.__name__}: the physics is read-only after the step (post_update)")
        return method(self, *args, **kwargs)

    return guarded


def pose_to_transform(pose: Pose) -> Transform:
    """(xyz, quaternion xyzw) of an SDF pose, PyBullet's pose form."""
    quat = pb.getQuaternionFromEuler(pose.rpy)
    return pose.xyz, (quat[0], quat[1], quat[2], quat[3])


def _as_transform(pos: Sequence[float], orn: Sequence[float]) -> Transform:
    x, y, z = pos
    qx, qy, qz, qw = orn
    return (float(x), float(y), float(z)), (float(qx), float(qy), float(qz), float(qw))


def compose(a: Transform, b: Transform) -> Transform:
    """a ∘ b for (position, quaternion) pairs."""
    return _as_transform(*pb.multiplyTransforms(a[0], a[1], b[0], b[1]))


def invert(a: Transform) -> Transform:
    """The inverse transform."""
    return _as_transform(*pb.invertTransform(a[0], a[1]))


@dataclass
class Body:
    """A model as loaded: its PyBullet id and its names."""

    name: str
    model: Model
    id: int
    links: dict[str, int]
    joints: dict[str, int]
    com_to_root: Transform
    """The root link's URDF frame seen from PyBullet's base (centre of mass) frame."""
    com_to_frame: Transform
    """The SDF model frame seen from PyBullet's base (centre of mass) frame."""
    urdf: str
    """The model's URDF (what `robot_description` publishes and the renderer draws). PyBullet may
    load it leaner (`Physics.fixed_castors`, `Physics.merge_fixed_links`): look links up here."""
    hosts: dict[str, str] = field(default_factory=dict)
    """Each link's host: the link PyBullet simulates it as part of (itself, or the link a chain of
    fixed joints ties it to, when fixed links are merged). `links` maps a link to its host's index."""
    drawn: tuple[str, ...] = ()
    """The joints that move in `urdf`: what the renderer poses."""
    held: frozenset[str] = frozenset()
    """Joints that move in `urdf` but that PyBullet holds fixed (ball castors): they read 0."""

    @property
    def indices(self) -> list[int]:
        """PyBullet's link indices of the body, each once (merged links share their host's), in order."""
        return sorted(set(self.links.values()))


@dataclass
class Physics:
    """A PyBullet world built from an SDF world description; stepped at the world's step size."""

    world: World
    fixed_castors: bool = True
    """Load ball castors fixed (`ball_castors`): 12 of the tug's 22 degrees of freedom gone, the same
    physics (a frictionless sphere turning about its centre moves nothing a collision sees)."""
    merge_fixed_links: bool = True
    """Load each chain of fixed joints as one link (PyBullet's URDF_MERGE_FIXED_LINKS): the tug's 21
    links become 5 (its base and four wheels), each costing the articulated-body solver and the
    broadphase as much as a moving one. A model with a contact or force/torque sensor keeps its links:
    those sensors read one link's contacts or one fixed joint's wrench."""
    client: int = field(init=False)
    bodies: dict[str, Body] = field(default_factory=dict)
    constraints: dict[int, tuple[str, str]] = field(default_factory=dict)
    """Joints made by `attach`: each one's (parent model, child model)."""
    _wheels: list[WheelFriction] = field(default_factory=list)
    _offsets: dict[tuple[str, str, Pose], Transform] = field(default_factory=dict)
    read_only: bool = False
    """True while post-update systems run: they read the step's result and change nothing."""
    _saved_state: int | None = None
    _saved_bodies: tuple[str, ...] = ()
    _ray_groups: dict[str, int] = field(default_factory=dict)
    _free_ray_groups: Iterator[int] = field(default_factory=ray_groups)
    _returned_ray_groups: list[int] = field(default_factory=list)
    """Groups of removed models, handed out again first (lowest first: the same world, the same groups)."""
    _heightfields: dict[str, list[int]] = field(default_factory=dict)
    """The heightfield bodies of each model's heightmaps (PyBullet bodies apart from the model's)."""
    _tmp: tempfile.TemporaryDirectory[str] = field(default_factory=tempfile.TemporaryDirectory)

    def __post_init__(self) -> None:
        self.client = pb.connect(pb.DIRECT)
        pb.setGravity(*self.world.gravity, physicsClientId=self.client)
        pb.setTimeStep(self.world.physics.max_step_size, physicsClientId=self.client)
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=self.client)

    @property
    def step_size(self) -> float:
        return self.world.physics.max_step_size

    def close(self) -> None:
        """Disconnects PyBullet and removes the generated URDF files."""
        if pb.isConnected(self.client):
            pb.disconnect(self.client)
        self._tmp.cleanup()

    # building

    @_changes_world
    def add_model(self, model: Model, name: str | None = None, pose: Pose | None = None) -> Body:
        """Loads `model` (through its URDF) as `name` at `pose` (default: the model's own pose).

        A model whose links form several joint trees is loaded as one body per tree (see
        `joint_trees`): the main one is `name` and is returned; each other is `name::<its root>`."""
        name = name or model.name
        main, *others = joint_trees(model)
        body = self._add_tree(main, name, pose)
        for part in others:
            self._add_tree(part, name + part.name.removeprefix(model.name), pose)
        return body

    def _add_tree(self, model: Model, name: str, pose: Pose | None) -> Body:
        """One tree of joints as one PyBullet body."""
        if name in self.bodies:
            raise ValueError(f"a model named {name!r} is already in the world")
        urdf_text = model_to_urdf(model, generated_dir=Path(self._tmp.name))
        castors = ball_castors(model)
        lean = _with_fixed_joints(urdf_text, castors) if self.fixed_castors else urdf_text
        urdf = Path(self._tmp.name) / f"{name}.urdf"
        urdf.write_text(lean)
        root = urdf_root(model)
        frame = pose_to_transform(pose if pose is not None else model.pose)
        root_pose = frame if root == "world" else compose(frame, pose_to_transform(link_frame(model.link(root))))
        merge = self.merge_fixed_links and not _reads_own_links(model)
        flags = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
        with quiet(1):
            body_id = pb.loadURDF(
                str(urdf),
                *root_pose,
                useFixedBase=model.static,
                flags=flags | (pb.URDF_MERGE_FIXED_LINKS if merge else 0),
                physicsClientId=self.client,
            )
        body = self._index(name, model, body_id, root, urdf_text, _fixed_hosts(lean) if merge else {})
        self.bodies[name] = body
        self._configure_joints(body)
        self._configure_friction(body)
        self._undamp(body)
        self._configure_castors(body, castors)
        self._add_heightfields(name, model, frame)
        return body

    @_changes_world
    def remove_model(self, name: str) -> list[str]:
        """Takes `name` out of the world with its further joint trees (`name::<root>`), its wheels'
        friction, its cached frames and its ray group (free for the next robot); returns the bodies'
        names. Joints made by `attach` are their system's to undo first."""
        self.body(name)
        names = [n for n in self.bodies if n == name or n.startswith(name + "::")]
        for part in names:
            body = self.bodies.pop(part)
            self._wheels = [w for w in self._wheels if w.body != body.id]
            self._offsets = {k: v for k, v in self._offsets.items() if k[0] != part}
            if (group := self._ray_groups.pop(part, None)) is not None:
                self._returned_ray_groups = sorted([*self._returned_ray_groups, group])
            for heightfield in self._heightfields.pop(part, []):
                pb.removeBody(heightfield, physicsClientId=self.client)
            pb.removeBody(body.id, physicsClientId=self.client)
        return names

    def _add_heightfields(self, name: str, model: Model, frame: Transform) -> None:
        """The heightmaps of a tree's collisions, each a body of its own, kept under `name` so that they leave with it."""
        for link in model.links:
            for collision in link.collisions:
                if isinstance(collision.geometry, Heightmap):
                    body = self._add_heightfield(model, link, collision, collision.geometry, frame)
                    if body is not None:
                        self._heightfields.setdefault(name, []).append(body)

    def _add_heightfield(
        self, model: Model, link: Link, collision: Collision, heightmap: Heightmap, frame: Transform
    ) -> int | None:
        """A heightmap's collision as a PyBullet heightfield fixed in the world, URDF having none;
        only in a static model, as Gazebo has it (the URDF carries the heightmap's visual)."""
        if not model.static:
            logger.warning(
                "model %r: heightmap %r is in a model that moves; Gazebo collides only static ones, and so does simbot",
                model.name,
                collision.name,
            )
            return None
        heights = heightmap_heights(heightmap, model.source)
        rows, cols = heights.shape
        shape = pb.createCollisionShape(
            pb.GEOM_HEIGHTFIELD,
            meshScale=(heightmap.size[0] / (cols - 1), heightmap.size[1] / (rows - 1), 1.0),
            heightfieldData=np.flipud(heights).ravel().tolist(),  # PyBullet's rows run along +x, from −y up
            numHeightfieldRows=cols,
            numHeightfieldColumns=rows,
            physicsClientId=self.client,
        )
        centre = (
            heightmap.pos[0],
            heightmap.pos[1],
            heightmap.pos[2] + (heights.min() + heights.max()) / 2.0,
        )  # Bullet centres its height range
        pose = compose(frame, pose_to_transform(link.pose @ collision.pose @ Pose(centre, (0.0, 0.0, 0.0))))
        body = pb.createMultiBody(0.0, shape, -1, *pose, physicsClientId=self.client)
        mu = collision.friction.mu if collision.friction else SDF_DEFAULT_MU
        pb.changeDynamics(body, -1, lateralFriction=mu, physicsClientId=self.client)
        return int(body)

    def _index(self, name: str, model: Model, body_id: int, root: str, urdf: str, hosts: dict[str, str]) -> Body:
        """The body's names: PyBullet's links and joints, then each merged link at its host's index."""
        links = {root: -1}
        joints, moving = {}, set()
        for j in range(pb.getNumJoints(body_id, physicsClientId=self.client)):
            info = pb.getJointInfo(body_id, j, physicsClientId=self.client)
            joints[info[1].decode()] = j
            links[info[12].decode()] = j
            if info[2] != pb.JOINT_FIXED:
                moving.add(info[1].decode())
        for link, host in hosts.items():
            links.setdefault(link, links[host])
        root_in_model = pose_to_transform(Pose() if root == "world" else link_frame(model.link(root)))
        com_to_root = invert(self._base_com(body_id))
        return Body(
            name, model, body_id, links, joints, com_to_root, compose(com_to_root, invert(root_in_model)), urdf,
            hosts={link: hosts.get(link, link) for link in links},
            drawn=(drawn := _moving_joints(urdf)),
            held=frozenset(drawn) - moving,
        )  # fmt: skip

    def _base_com(self, body_id: int) -> Transform:
        """The base's centre of mass in its link frame."""
        info = pb.getDynamicsInfo(body_id, -1, physicsClientId=self.client)
        return _as_transform(info[3], info[4])

    def _configure_joints(self, body: Body) -> None:
        """PyBullet puts a velocity motor on every joint; SDF joints are passive until a system drives them."""
        sdf_joints = {joint.name: joint for joint in body.model.joints}
        for urdf_name, index in body.joints.items():
            joint = sdf_joints.get(urdf_name.split("__", 1)[0])  # a ball joint's three parts are JOINT__yaw, ...
            if joint is not None:
                friction = joint.axis.friction if joint.axis else 0.0
                pb.setJointMotorControl2(
                    body.id, index, pb.VELOCITY_CONTROL, force=friction, physicsClientId=self.client
                )

    def _configure_friction(self, body: Body) -> None:
        """SDF μ per link; wheels with μ ≠ μ2 get the anisotropic model PyBullet lacks (see wheel_friction).
        A merged link's collisions take their host's μ (the tug's castors, the chassis's)."""
        wheels = []
        for link in body.model.links:
            index = body.links.get(link.name)
            if index is None or body.hosts[link.name] != link.name:
                continue
            friction = next((c.friction for c in link.collisions if c.friction is not None), None)
            mu = friction.mu if friction else SDF_DEFAULT_MU
            joint = self._wheel_joint(body.model, link.name) if friction and friction.mu != friction.mu2 else None
            if friction and joint is not None and joint.axis is not None:
                fdir1 = _fdir1_angle(body.model, joint, friction.fdir1)
                wheels.append(Wheel(index, friction.mu, friction.mu2, _axis_in_link(joint, link.pose), fdir1))
                mu = 0.0
            pb.changeDynamics(
                body.id, index, lateralFriction=mu, rollingFriction=0, spinningFriction=0, physicsClientId=self.client
            )
        if wheels:
            self._wheels.append(WheelFriction(self.client, body.id, tuple(wheels)))
            self._soften_tyres(body, wheels)

    def _soften_tyres(self, body: Body, wheels: list[Wheel]) -> None:
        """Tyre compliance, critically damped for each wheel's share of the body's mass."""
        mass = sum(pb.getDynamicsInfo(body.id, i, physicsClientId=self.client)[0] for i in body.indices)
        damping = 2.0 * math.sqrt(TYRE_STIFFNESS * mass / len(wheels))
        for wheel in wheels:
            pb.changeDynamics(
                body.id,
                wheel.link,
                contactStiffness=TYRE_STIFFNESS,
                contactDamping=damping,
                physicsClientId=self.client,
            )

    def _configure_castors(self, body: Body, castors: frozenset[str]) -> None:
        """A ball castor's sphere passes no friction (an ideal castor's ball spins instead, and so must
        a fixed one) and makes no contact until it touches: hanging 2 cm up, within Bullet's 2 cm
        contact margin, it would otherwise put 8 idle contacts per tug into the solver every step.
        A castor merged into its host (`merge_fixed_links`) is the host's to configure."""
        for joint in body.model.joints:
            if joint.name in castors and body.hosts[joint.child] == joint.child:
                pb.changeDynamics(
                    body.id,
                    body.links[joint.child],
                    lateralFriction=0.0,
                    contactProcessingThreshold=0.0,
                    physicsClientId=self.client,
                )

    @staticmethod
    def _wheel_joint(model: Model, link: str) -> Joint | None:
        return next((j for j in model.joints if j.child == link and j.type in ("revolute", "continuous")), None)

    @contextmanager
    def reading(self) -> Iterator[None]:
        """The world read-only for the duration (the post-update phase)."""
        self.read_only = True
        try:
            yield
        finally:
            self.read_only = False

    def save_initial_state(self) -> None:
        """Remembers the world as built, for `reset`."""
        self._saved_state = pb.saveState(physicsClientId=self.client)
        self._saved_bodies = tuple(self.bodies)

    # stepping

    @_changes_world
    def step(self) -> None:
        """One physics step: wheel friction from the last contacts, then PyBullet."""
        for wheels in self._wheels:
            wheels.apply()
        pb.stepSimulation(physicsClientId=self.client)

    @_changes_world
    def reset(self) -> None:
        """Every body back to where it was built, at rest; detachable joints are the systems' to undo.
        PyBullet restores bodies by their order: the world must hold the bodies it was saved with."""
        if tuple(self.bodies) != self._saved_bodies:
            gone = sorted(set(self._saved_bodies) - set(self.bodies))
            raise ValueError(f"reset: the world as started held {', '.join(gone)}, removed since; restart the server")
        if self._saved_state is not None:
            pb.restoreState(self._saved_state, physicsClientId=self.client)

    # state, by name

    def body(self, model: str) -> Body:
        try:
            return self.bodies[model]
        except KeyError:
            raise KeyError(f"no model named {model!r} in the world (models: {', '.join(self.bodies)})") from None

    def model_pose(self, model: str) -> Transform:
        """The model frame in the world (SDF semantics: not the centre of mass)."""
        body = self.body(model)
        com = _as_transform(*pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client))
        return compose(com, body.com_to_frame)

    @_changes_world
    def set_model_pose(self, model: str, pose: Transform) -> None:
        """Teleports the model frame to `pose` and stops it."""
        body = self.body(model)
        com = compose(pose, invert(body.com_to_frame))
        pb.resetBasePositionAndOrientation(body.id, *com, physicsClientId=self.client)
        pb.resetBaseVelocity(body.id, (0, 0, 0), (0, 0, 0), physicsClientId=self.client)

    def frame_pose(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> Transform:
        """World pose of a frame fixed to `link`, given in the SDF link frame (where a sensor is)."""
        return self.frame_motion(model, link, pose_in_link)[0]

    def _offset(self, body: Body, link: str, pose_in_link: Pose) -> Transform:
        """The frame in the link's URDF frame; worked out once (sensors ask hundreds of times a second)."""
        key = (body.name, link, pose_in_link)
        offset = self._offsets.get(key)
        if offset is None:
            host = body.hosts.get(link, link)
            host_frame = IDENTITY if host == "world" else link_frame(body.model.link(host))
            offset = self._offsets[key] = pose_to_transform(
                host_frame.inverse() @ body.model.link(link).pose @ pose_in_link
            )
        return offset

    def frame_motion(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> tuple[Transform, Vec3, Vec3]:
        """(world pose, linear velocity of the frame's origin, angular velocity), velocities in the
        world frame; current even right after a teleport (forward kinematics are recomputed)."""
        body = self.body(model)
        index = self._link(body, link)
        if index == -1:
            com, orn = pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client)
            linear, angular = pb.getBaseVelocity(body.id, physicsClientId=self.client)
            frame = compose(_as_transform(com, orn), body.com_to_root)
        else:
            state = pb.getLinkState(
                body.id, index, computeLinkVelocity=True, computeForwardKinematics=True, physicsClientId=self.client
            )
            com, linear, angular = state[0], state[6], state[7]
            frame = _as_transform(state[4], state[5])
        pose = compose(frame, self._offset(body, link, pose_in_link))
        (wx, wy, wz), (rx, ry, rz) = angular, (pose[0][0] - com[0], pose[0][1] - com[1], pose[0][2] - com[2])
        velocity = (
            linear[0] + wy * rz - wz * ry,
            linear[1] + wz * rx - wx * rz,
            linear[2] + wx * ry - wy * rx,
        )  # v + ω × r
        return pose, velocity, (float(wx), float(wy), float(wz))

    def blind_rays_to(self, model: str) -> int:
        """Gives `model` a ray group of its own (once; call it before stepping, as a sensor's setup
        does): rays cast `blind_to` it pass through it and hit every other body. Returns the group."""
        group = self._ray_groups.get(model)
        if group is None:
            body = self.body(model)
            group = self._returned_ray_groups.pop(0) if self._returned_ray_groups else next(self._free_ray_groups, None)
            if group is None:
                raise ValueError(f"model {model!r}: more robots carry ray sensors than there are ray groups")
            for index in body.indices:  # in index order: Bullet re-adds the proxies in it
                pb.setCollisionFilterGroupMask(body.id, index, group, -1, physicsClientId=self.client)
            self._ray_groups[model] = group
        return group

    def cast_rays(
        self, starts: npt.NDArray[np.float64], ends: npt.NDArray[np.float64], blind_to: str | None = None
    ) -> npt.NDArray[np.float64]:
        """Fraction of each ray (N×3 starts to N×3 ends) to its first hit, NaN where it hits nothing;
        the rays pass through the model `blind_to` (the sensor's own robot) and no other. Cast in
        batches under PyBullet's most (a 3-D lidar casts more): it refuses more than 16384 rays and
        answers exactly 16384 with one result short."""
        mask = ~self.blind_rays_to(blind_to) if blind_to is not None else -1
        batch = pb.MAX_RAY_INTERSECTION_BATCH_SIZE - 1
        hits = [
            hit
            for first in range(0, len(starts), batch)
            for hit in pb.rayTestBatch(
                starts[first : first + batch],
                ends[first : first + batch],
                collisionFilterMask=mask,
                physicsClientId=self.client,
            )
        ]
        return np.array([hit[2] if hit[0] >= 0 else np.nan for hit in hits], dtype=float)

    # sensors' queries: contacts, joint wrenches (read-only, but for the one load-time hook)

    def link_contacts(self, model: str, link: str) -> list[ContactPoint]:
        """The points where `link` touches other bodies after the last step, with the forces on it."""
        body = self.body(model)
        points = pb.getContactPoints(bodyA=body.id, linkIndexA=self._link(body, link), physicsClientId=self.client)
        return [self._contact_point(point) for point in points]

    def _contact_point(self, point: tuple[Any, ...]) -> ContactPoint:
        """One of PyBullet's contact points, its other body by name (model, link; "" for a body built
        outside a model, a heightfield). PyBullet turns the normal round when it swaps the pair to put
        the asked body first, but not the friction directions, which it builds as a right-handed
        (normal, dir1, dir2): where they are left-handed with the reported normal, the pair was swapped
        and the friction forces on the asked body are the opposite of the reported ones."""
        a, b, normal, dir_1, dir_2 = (np.asarray(point[i], dtype=float) for i in (5, 6, 7, 11, 13))
        swapped = float(np.dot(dir_2, np.cross(normal, dir_1))) < 0
        friction = (point[10] * dir_1 + point[12] * dir_2) * (-1.0 if swapped else 1.0)
        return ContactPoint(
            self._names_of(point[2], point[4]),
            _vec3((a + b) / 2),
            _vec3(normal),
            -float(point[8]),
            _vec3(point[9] * normal + friction),
        )

    def _names_of(self, body_id: int, index: int) -> tuple[str, str]:
        for body in self.bodies.values():
            if body.id == body_id:
                return body.name, next((name for name, i in body.links.items() if i == index), "")
        return "", ""

    @_changes_world
    def measure_joint_wrench(self, model: str, joint: str) -> None:
        """Switches on PyBullet's reaction force sensor of a joint, which `joint_wrench` reads: a
        force/torque sensor asks for it when it is built, before the first step."""
        body = self.body(model)
        pb.enableJointForceTorqueSensor(body.id, self._joint(body, joint), True, physicsClientId=self.client)

    def joint_wrench(self, model: str, joint: str) -> tuple[Vec3, Vec3, Vec3]:
        """(force, torque, point): what the parent applied to the child through `joint` in the last
        step, in the world frame, the torque about `point`, the child's centre of mass (where PyBullet
        reports it). Needs `measure_joint_wrench` first."""
        body = self.body(model)
        index = self._joint(body, joint)
        reaction = pb.getJointState(body.id, index, physicsClientId=self.client)[2]
        com, orn = pb.getLinkState(body.id, index, computeForwardKinematics=True, physicsClientId=self.client)[:2]
        rotation = np.array(pb.getMatrixFromQuaternion(orn), dtype=float).reshape(3, 3)
        return _vec3(rotation @ reaction[:3]), _vec3(rotation @ reaction[3:]), _vec3(com)

    def moving_bodies(self) -> list[str]:
        """Names of the models that can move (not static)."""
        return [name for name, body in self.bodies.items() if not body.model.static]

    def body_state(self, model: str) -> tuple[Transform, dict[str, float]]:
        """The root link's URDF frame in the world and the position of every joint of the model's
        URDF (`Body.urdf`) that can move there, by name: enough to redraw the body from that URDF."""
        body = self.body(model)
        com = _as_transform(*pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client))
        states = self.joint_states(model, list(body.drawn))
        return compose(com, body.com_to_root), {name: state[0] for name, state in zip(body.drawn, states)}

    def _link(self, body: Body, link: str) -> int:
        try:
            return body.links[link]
        except KeyError:
            raise KeyError(f"model {body.name!r} has no link {link!r}") from None

    def _joint(self, body: Body, joint: str) -> int:
        try:
            return body.joints[joint]
        except KeyError:
            raise KeyError(f"model {body.name!r} has no movable joint {joint!r}") from None

    def joint_states(self, model: str, joints: list[str]) -> list[tuple[float, float, float]]:
        """(position, velocity, motor effort) of each named joint; zeros for a joint held fixed (`Body.held`)."""
        body = self.body(model)
        moving = [j for j in joints if j not in body.held]
        indices = [self._joint(body, j) for j in moving]
        states = pb.getJointStates(body.id, indices, physicsClientId=self.client) if indices else []
        found = {name: (float(s[0]), float(s[1]), float(s[3])) for name, s in zip(moving, states)}
        return [found.get(j, (0.0, 0.0, 0.0)) for j in joints]

    @_changes_world
    def set_joint_velocity(self, model: str, joint: str, velocity: float, max_effort: float) -> None:
        """Drives a joint at `velocity` with at most `max_effort` (N·m or N), as a velocity servo."""
        body = self.body(model)
        pb.setJointMotorControl2(
            body.id,
            self._joint(body, joint),
            pb.VELOCITY_CONTROL,
            targetVelocity=velocity,
            force=max_effort,
            physicsClientId=self.client,
        )

    # model and joint commands of the Gazebo systems (VelocityControl, ApplyJointForce, joint controllers)

    def _undamp(self, body: Body) -> None:
        """No velocity damping: SDF states none, and Gazebo applies none. PyBullet's default (0.04
        linear and quadratic) takes 8 % of a joint's speed after 1 s at 5 rad/s, so a torque would
        not accelerate a link as τ/I predicts."""
        pb.changeDynamics(body.id, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=self.client)

    @_changes_world
    def set_joint_force(self, model: str, joint: str, force: float) -> None:
        """Applies `force` (N·m or N) on a joint for the next step only, as Gazebo's JointForceCmd:
        a controller commands it every step. The joint's friction motor keeps acting."""
        body = self.body(model)
        pb.setJointMotorControl2(
            body.id, self._joint(body, joint), pb.TORQUE_CONTROL, force=force, physicsClientId=self.client
        )

    def model_motion(self, model: str) -> tuple[Transform, Vec3, Vec3]:
        """(model frame in the world, linear velocity of its origin, angular velocity), in the world frame."""
        body = self.body(model)
        com = _as_transform(*pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client))
        linear, angular = pb.getBaseVelocity(body.id, physicsClientId=self.client)
        frame = compose(com, body.com_to_frame)
        offset = np.subtract(frame[0], com[0])
        velocity = np.add(linear, np.cross(angular, offset))
        return frame, _vec3(velocity), _vec3(angular)

    @_changes_world
    def set_model_velocity(self, model: str, linear: Vec3, angular: Vec3) -> None:
        """Sets the model frame's velocity, both vectors given in the model frame (Gazebo's
        LinearVelocityCmd and AngularVelocityCmd): what VelocityControl commands before each step."""
        body = self.body(model)
        com = _as_transform(*pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client))
        frame = compose(com, body.com_to_frame)
        rotation = np.reshape(pb.getMatrixFromQuaternion(frame[1]), (3, 3))
        angular_world = rotation @ np.asarray(angular)
        linear_world = rotation @ np.asarray(linear) + np.cross(angular_world, np.subtract(com[0], frame[0]))
        pb.resetBaseVelocity(body.id, _vec3(linear_world), _vec3(angular_world), physicsClientId=self.client)

    @_changes_world
    def attach(self, parent: tuple[str, str], child: tuple[str, str]) -> int:
        """Fixes child (model, link) to parent (model, link) at their current relative pose."""
        pbody, plink, pcom = self._com_frame(*parent)
        cbody, clink, ccom = self._com_frame(*child)
        relative = compose(invert(pcom), ccom)
        cid = pb.createConstraint(
            pbody, plink, cbody, clink, pb.JOINT_FIXED, (0, 0, 0), relative[0], (0, 0, 0), relative[1], (0, 0, 0, 1),
            physicsClientId=self.client,
        )  # fmt: skip
        pb.changeConstraint(cid, maxForce=FIXED_CONSTRAINT_FORCE, physicsClientId=self.client)
        self.constraints[cid] = (parent[0], child[0])
        return cid

    def holder(self, model: str) -> str | None:
        """The model that a joint made by `attach` fixes `model` to, if one does (a fleet shares a trolley)."""
        return next((parent for parent, child in self.constraints.values() if child == model), None)

    def _com_frame(self, model: str, link: str) -> tuple[int, int, Transform]:
        """(body id, link index, the link's centre-of-mass frame in the world): PyBullet constrains those."""
        body = self.body(model)
        index = self._link(body, link)
        if index == -1:
            return (
                body.id,
                index,
                _as_transform(*pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client)),
            )
        state = pb.getLinkState(body.id, index, physicsClientId=self.client)
        return body.id, index, _as_transform(state[0], state[1])

    @_changes_world
    def detach(self, constraint: int) -> None:
        """Removes a joint made by `attach`."""
        if self.constraints.pop(constraint, None) is not None:
            pb.removeConstraint(constraint, physicsClientId=self.client)


def _vec3(values: Sequence[float] | npt.NDArray[np.float64]) -> Vec3:
    return float(values[0]), float(values[1]), float(values[2])


def _fdir1_angle(model: Model, joint: Joint, fdir1: Vec3 | None) -> float:
    """SDF's fdir1 of a wheel as its angle from the rolling direction on level ground. fdir1 is
    read in the frame of the wheel joint's parent link (the chassis), where Gazebo's mecanum
    example states it with `gz:expressed_in`: the wheel's own frame spins."""
    if fdir1 is None or joint.axis is None:
        return 0.0
    up = np.array([0.0, 0.0, 1.0])
    axle = joint.pose.matrix()[:3, :3] @ np.asarray(joint.axis.xyz)
    along = np.cross(axle, up)
    if np.linalg.norm(along) < 1e-9:
        return 0.0
    across = np.cross(up, along)
    parent = next((link.pose for link in model.links if link.name == joint.parent), IDENTITY)
    direction = parent.matrix()[:3, :3] @ np.asarray(fdir1)
    return float(math.atan2(direction @ across, direction @ along))


@dataclass(frozen=True)
class ContactPoint:
    """A point where a link touches another body (`Physics.link_contacts`), in the world frame."""

    other: tuple[str, str]
    """(model, link) touched."""
    position: Vec3
    normal: Vec3
    """Unit, from the other body towards the link."""
    depth: float
    """Penetration, positive where the two overlap."""
    force: Vec3
    """On the link: normal force and friction."""


def ball_castors(model: Model) -> frozenset[str]:
    """The model's ball castors: ball joints whose child ends its chain, carries no sensor and
    collides only as spheres centred on the joint, with no joint friction or damping.

    Turning such a sphere about its centre moves nothing a collision sees, and with a massless
    gimbal the ball passes no tangential force: it is a frictionless sphere, and may be loaded fixed
    in place, its three gimbal joints out of PyBullet's multibody, whose cost per contact grows with
    the degrees of freedom (the tug's 12 castor joints are 12 of its 22: benchmarks/bench_fleet.py).
    """
    parents = {joint.parent for joint in model.joints}
    links = {link.name: link for link in model.links}
    return frozenset(
        joint.name
        for joint in model.joints
        if joint.type == "ball"
        and joint.child not in parents
        and (joint.axis is None or joint.axis.friction == joint.axis.damping == 0.0)
        and _sphere_on(links[joint.child], joint.pose)
    )


def _sphere_on(link: Link, centre: Pose) -> bool:
    """Whether `link` collides, only as spheres centred on `centre` (model frame), and carries no sensor."""
    if link.sensors or not link.collisions:
        return False
    for collision in link.collisions:
        at = (link.pose @ collision.pose).xyz
        if not isinstance(collision.geometry, Sphere) or math.dist(at, centre.xyz) > 1e-9:
            return False
    return True


def _reads_own_links(model: Model) -> bool:
    """Whether a sensor of `model` reads a link's own contacts or a fixed joint's wrench, which merging
    fixed links would pool with its neighbours' or take away."""
    return any(sensor.type in ("contact", "force_torque") for _, sensor in model.sensors())


def _fixed_hosts(urdf: str) -> dict[str, str]:
    """Each link of `urdf` that a fixed joint ties to its parent, and the link it merges into (up the
    chain of fixed joints): what PyBullet's URDF_MERGE_FIXED_LINKS does."""
    parents = {
        joint.find("child").get("link", ""): (joint.find("parent").get("link", ""), joint.get("type"))  # type: ignore[union-attr]
        for joint in ET.fromstring(urdf).iter("joint")
    }
    hosts = {}
    for link in parents:
        host = link
        while host in parents and parents[host][1] == "fixed":
            host = parents[host][0]
        if host != link:
            hosts[link] = host
    return hosts


def _moving_joints(urdf: str) -> tuple[str, ...]:
    """The names of the joints of `urdf` that are not fixed."""
    return tuple(joint.get("name", "") for joint in ET.fromstring(urdf).iter("joint") if joint.get("type") != "fixed")


def _with_fixed_joints(urdf: str, joints: frozenset[str]) -> str:
    """The URDF with the parts of `joints` (a ball joint's are JOINT__yaw, ...) made fixed; links
    and joints keep their names (`Body.held` tells which moving joints PyBullet holds)."""
    if not joints:
        return urdf
    root = ET.fromstring(urdf)
    for joint in root.iter("joint"):
        if joint.get("name", "").split("__", 1)[0] in joints:
            joint.set("type", "fixed")
    return ET.tostring(root, encoding="unicode")


def _axis_in_link(joint: Joint, link_pose: Pose) -> tuple[float, float, float]:
    """A joint's axis (given in the joint frame) in its child link's frame; both poses are in the model frame."""
    assert joint.axis is not None
    rotation = (link_pose.inverse() @ joint.pose).matrix()[:3, :3]
    x, y, z = rotation @ joint.axis.xyz
    return float(x), float(y), float(z)
