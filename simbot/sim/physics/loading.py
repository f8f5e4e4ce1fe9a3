"""SDF models into PyBullet bodies: a tree of joints written as URDF and loaded, leaner where the
physics allows (ball castors fixed, fixed links merged), its names indexed, its dynamics and its
heightmaps set as SDF states them."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from simbot.description.actor_scripts import is_actor
from simbot.description.kinematics import KinematicTree
from simbot.description.model import Link, Model, Sphere
from simbot.description.poses import Pose
from simbot.description.urdf_writer import link_frame, model_to_urdf_held, urdf_root
from simbot.sim.bullet import pb, quiet
from simbot.sim.physics.body import Body
from simbot.sim.physics.bullet_transforms import compose, invert, pose_to_transform
from simbot.sim.physics.dynamics import configure
from simbot.sim.physics.heightfields import add_heightfields
from simbot.sim.physics.wheel_friction import WheelFriction
from simbot.transform import Transform


@dataclass(frozen=True)
class Loaded:
    """One tree of joints in PyBullet: its body, its wheels' friction model, its heightfield bodies."""

    body: Body
    wheels: WheelFriction | None
    heightfields: list[int]


@dataclass(frozen=True)
class Loader:
    """Loads trees of joints into the PyBullet world `client`, their URDF files in `folder`."""

    client: int
    folder: Path
    fixed_castors: bool
    """Load ball castors fixed (see `Physics.fixed_castors`)."""
    merge_fixed_links: bool
    """Load each chain of fixed joints as one link (see `Physics.merge_fixed_links`)."""

    def load(self, model: Model, name: str, pose: Pose | None) -> Loaded:
        """`model`, one tree of joints, as the body `name` with its model frame at `pose` (default: the model's own)."""
        frame = pose_to_transform(pose if pose is not None else model.pose)
        body = self._load_urdf(model, name, frame)
        return Loaded(body, configure(self.client, body), add_heightfields(self.client, model, frame))

    def _load_urdf(self, model: Model, name: str, frame: Transform) -> Body:
        """The tree's URDF loaded (leaner where it may be), and its names indexed."""
        castors = ball_castors(model)
        held = castors if self.fixed_castors else frozenset()
        merge = self.merge_fixed_links and not _reads_own_links(model)
        urdf, lean = model_to_urdf_held(model, held, self.folder)
        root = urdf_root(model)
        body_id = self._load_file(model, name, lean, root, frame, merge)
        tree = KinematicTree.of_urdf(urdf)
        hosts = tree.fixed_hosts({joint.name for joint in tree.joints if joint.part_of(held)}) if merge else {}
        links, joints, moving = self._names(body_id, root, hosts)
        root_in_model = pose_to_transform(Pose() if root == "world" else link_frame(model.link(root)))
        com_to_root = invert(self._base_com(body_id))
        drawn = tuple(joint.name for joint in tree.moving())
        return Body(
            name, model, body_id, links, joints, com_to_root, compose(com_to_root, invert(root_in_model)), urdf, tree,
            castors, hosts={link: hosts.get(link, link) for link in links}, drawn=drawn, held=frozenset(drawn) - moving,
        )  # fmt: skip

    def _load_file(self, model: Model, name: str, urdf: str, root: str, frame: Transform, merge: bool) -> int:
        """PyBullet's body of `urdf`, written to the folder as `name`, its root link placed for the model frame at `frame`."""
        path = self.folder / f"{name}.urdf"
        path.write_text(urdf)
        root_pose = frame if root == "world" else compose(frame, pose_to_transform(link_frame(model.link(root))))
        flags = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
        with quiet(1):
            body_id = pb.loadURDF(
                str(path),
                *root_pose,
                useFixedBase=model.static or is_actor(model),  # an actor: kinematic, moved by its script
                flags=flags | (pb.URDF_MERGE_FIXED_LINKS if merge else 0),
                physicsClientId=self.client,
            )
        return int(body_id)

    def _names(self, body_id: int, root: str, hosts: dict[str, str]) -> tuple[dict[str, int], dict[str, int], set[str]]:
        """(links, joints, moving joints): PyBullet's links and joints by name, then each merged link at its host's index."""
        links, joints, moving = {root: -1}, {}, set()
        for j in range(pb.getNumJoints(body_id, physicsClientId=self.client)):
            info = pb.getJointInfo(body_id, j, physicsClientId=self.client)
            joints[info[1].decode()] = j
            links[info[12].decode()] = j
            if info[2] != pb.JOINT_FIXED:
                moving.add(info[1].decode())
        for link, host in hosts.items():
            links.setdefault(link, links[host])
        return links, joints, moving

    def _base_com(self, body_id: int) -> Transform:
        """The base's centre of mass in its link frame."""
        info = pb.getDynamicsInfo(body_id, -1, physicsClientId=self.client)
        return Transform.of(info[3], info[4])


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
