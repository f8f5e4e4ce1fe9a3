"""What systems read of the world, by name: poses, motions, joint states, contacts, wrenches, rays.
The `Physics` class's read half (`WorldReader`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from simbot.description.kinematics import KinematicTree
from simbot.description.model import Model, World
from simbot.description.poses import IDENTITY, Pose
from simbot.description.urdf_writer import link_frame
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Body
from simbot.sim.physics.bullet_transforms import compose, pose_to_transform, vec3
from simbot.sim.physics.contacts import ContactPoint, contact_point
from simbot.sim.physics.protocols import Frame, FrameMotions, RayBatch
from simbot.sim.physics.rays import Rays
from simbot.sim.physics.stepping import Stepper
from simbot.transform import Transform, Vec3, matmul, quaternion_products, rotate_many

FRAME_SETS_KEPT = 4
"""Sets of frames asked for together that `frame_motions` keeps worked out (a world's IMUs, its lidars)."""


class Queries:
    """Reading the world; the state it reads is `Physics`'s."""

    world: World
    client: int
    bodies: dict[str, Body]
    constraints: dict[int, tuple[str, str]]
    """Joints made by `attach`: each one's (parent model, child model)."""
    _rays: Rays
    _offsets: dict[tuple[str, str, Pose], Transform]
    """Frames fixed to links, in their link's URDF frame (`_offset`)."""
    _frame_sets: list[tuple[list[Frame], tuple[list[int], npt.NDArray[np.float64]] | None]]
    """The last few sets of frames asked for at once, newest first, and what `_on_bases` found of them."""
    _stepper: Stepper

    @property
    def step_size(self) -> float:
        return self.world.physics.max_step_size

    # the bodies

    def body(self, model: str) -> Body:
        try:
            return self.bodies[model]
        except KeyError:
            raise KeyError(f"no model named {model!r} in the world (models: {', '.join(self.bodies)})") from None

    def body_names(self) -> list[str]:
        """Every body's name, in the order they were added."""
        return list(self.bodies)

    def model_of(self, model: str) -> Model:
        """The description a body was loaded from (one tree of joints of its model: see `Physics.add_model`)."""
        return self.body(model).model

    def urdf_of(self, model: str) -> str:
        """The body's URDF, as the renderer draws it and `body_state` poses it."""
        return self.body(model).urdf

    def kinematics(self, model: str) -> KinematicTree:
        """The links and joints of the body's URDF (`urdf_of`)."""
        return self.body(model).tree

    def held_joints(self, model: str) -> frozenset[str]:
        """Joints that move in the body's URDF but that the physics holds fixed (ball castors): they read 0."""
        return self.body(model).held

    def moving_bodies(self) -> list[str]:
        """Names of the models that can move (not static)."""
        return [name for name, body in self.bodies.items() if not body.model.static]

    def holder(self, model: str) -> str | None:
        """The model that a joint made by `attach` fixes `model` to, if one does (a fleet shares a trolley)."""
        return next((parent for parent, child in self.constraints.values() if child == model), None)

    # poses and motions

    def model_pose(self, model: str) -> Transform:
        """The model frame in the world (SDF semantics: not the centre of mass)."""
        body = self.body(model)
        return compose(self._base(body), body.com_to_frame)

    def model_motion(self, model: str) -> tuple[Transform, Vec3, Vec3]:
        """(model frame in the world, linear velocity of its origin, angular velocity), in the world frame."""
        body = self.body(model)
        com, linear, angular = self._base_motion(body)
        frame = compose(com, body.com_to_frame)
        offset = np.subtract(frame[0], com[0])
        velocity = np.add(linear, np.cross(angular, offset))
        return frame, vec3(velocity), vec3(angular)

    def frame_pose(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> Transform:
        """World pose of a frame fixed to `link`, given in the SDF link frame (where a sensor is)."""
        return self.frame_motion(model, link, pose_in_link)[0]

    def frame_motion(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> tuple[Transform, Vec3, Vec3]:
        """(world pose, linear velocity of the frame's origin, angular velocity), velocities in the
        world frame; current even right after a teleport (forward kinematics are recomputed)."""
        pose, com, linear, angular = self._frame_state(model, link, pose_in_link)
        (wx, wy, wz), (rx, ry, rz) = angular, (pose[0][0] - com[0], pose[0][1] - com[1], pose[0][2] - com[2])
        velocity = (
            linear[0] + wy * rz - wz * ry,
            linear[1] + wz * rx - wx * rz,
            linear[2] + wx * ry - wy * rx,
        )  # v + ω × r
        return pose, velocity, (float(wx), float(wy), float(wz))

    def frame_motions(self, frames: Sequence[Frame]) -> FrameMotions:
        """`frame_motion` of many frames at once (a fleet's IMUs), as arrays: frames fixed to their
        bodies' bases from one query of the bases (a kinematic fleet's rows), others link by link."""
        on_bases = self._on_bases(frames)
        if on_bases is not None:
            return self._base_frame_motions(*on_bases)
        rows = []
        for frame in frames:
            (position, orientation), com, linear, angular = self._frame_state(*frame)
            rows.append((*position, *orientation, *com, *linear, *angular))
        table = np.array(rows, dtype=float).reshape(-1, 16)  # pose 7, centre of mass 3, v 3, ω 3
        velocities = _origin_velocities(table[:, 10:13], table[:, 13:], table[:, :3] - table[:, 7:10])
        return FrameMotions(table[:, :3], table[:, 3:7], velocities, table[:, 13:])

    def _on_base(self, model: str, link: str, pose_in_link: Pose) -> tuple[int, Transform] | None:
        """(body id, the frame in its base's centre-of-mass frame) of a frame fixed to its body's
        root link (or a link merged into it); None for a frame on another link."""
        body = self.body(model)
        if body.link_index(link) != -1:
            return None
        return body.id, compose(body.com_to_root, self._offset(body, link, pose_in_link))

    def _on_bases(self, frames: Sequence[Frame]) -> tuple[list[int], npt.NDArray[np.float64]] | None:
        """(the bodies, each frame in its base's centre-of-mass frame as a row: position, quaternion)
        of frames all fixed to bases, None otherwise; kept for the same frames asked again (a fleet's
        IMUs every step: a comparison of the same tuples) until a body enters or leaves."""
        for asked, found in self._frame_sets:
            if asked == frames:
                return found
        on_bases = [self._on_base(*frame) for frame in frames]
        found = None
        if None not in on_bases:
            ids = [body for body, _ in on_bases]  # type: ignore[misc]
            offsets = np.array([(*at, *turn) for _, (at, turn) in on_bases], dtype=np.float64)  # type: ignore[misc]
            found = ids, offsets.reshape(-1, 7)
        self._frame_sets[:] = [(list(frames), found), *self._frame_sets[: FRAME_SETS_KEPT - 1]]
        return found

    def _base_frame_motions(self, ids: list[int], offsets: npt.NDArray[np.float64]) -> FrameMotions:
        """Frames fixed to bases (`_on_bases`), their motions from their bases' at once."""
        bases = self._stepper.bases(ids)
        positions = bases.positions + rotate_many(bases.orientations, offsets[:, :3])
        orientations = quaternion_products(bases.orientations, offsets[:, 3:])
        velocities = _origin_velocities(bases.linear, bases.angular, positions - bases.positions)
        return FrameMotions(positions, orientations, velocities, bases.angular)

    def _frame_state(self, model: str, link: str, pose_in_link: Pose) -> tuple[Transform, Vec3, Vec3, Vec3]:
        """(the frame's world pose, its link's centre of mass, that centre's linear velocity, the
        angular velocity), as PyBullet reports them."""
        body = self.body(model)
        index = body.link_index(link)
        if index == -1:
            base, linear, angular = self._base_motion(body)
            com, frame = base.position, compose(base, body.com_to_root)
        else:
            self._stepper.sync()
            state = pb.getLinkState(
                body.id, index, computeLinkVelocity=True, computeForwardKinematics=True, physicsClientId=self.client
            )
            com, linear, angular = state[0], state[6], state[7]
            frame = Transform.of(state[4], state[5])
        return compose(frame, self._offset(body, link, pose_in_link)), com, linear, angular

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

    def _base(self, body: Body) -> Transform:
        """PyBullet's base frame (the root link's centre of mass) in the world."""
        return self._base_motion(body)[0]

    def _base_motion(self, body: Body) -> tuple[Transform, Vec3, Vec3]:
        """(the base frame in the world, its linear velocity, the angular velocity), as the stepper holds them."""
        base = self._stepper.bases([body.id])
        return Transform.of(base.positions[0], base.orientations[0]), vec3(base.linear[0]), vec3(base.angular[0])

    # joints

    def joint_states(self, model: str, joints: list[str]) -> list[tuple[float, float, float]]:
        """(position, velocity, motor effort) of each named joint; zeros for a joint held fixed (`held_joints`)."""
        body = self.body(model)
        if body.held.isdisjoint(joints):  # most reads (a fleet's encoders, 50 times a second each)
            return self._stepper.joint_states(body.id, [body.joint_index(j) for j in joints])
        moving = [j for j in joints if j not in body.held]
        indices = [body.joint_index(j) for j in moving]
        found = dict(zip(moving, self._stepper.joint_states(body.id, indices)))
        return [found.get(j, (0.0, 0.0, 0.0)) for j in joints]

    def body_state(self, model: str) -> tuple[Transform, dict[str, float]]:
        """The root link's URDF frame in the world and the position of every joint of the model's
        URDF (`urdf_of`) that can move there, by name: enough to redraw the body from that URDF."""
        body = self.body(model)
        states = self.joint_states(model, list(body.drawn))
        return compose(self._base(body), body.com_to_root), {name: state[0] for name, state in zip(body.drawn, states)}

    # sensors' queries: contacts, joint wrenches, rays

    def link_contacts(self, model: str, link: str) -> list[ContactPoint]:
        """The points where `link` touches other bodies after the last step, with the forces on it."""
        body = self.body(model)
        self._stepper.sync()
        points = pb.getContactPoints(bodyA=body.id, linkIndexA=body.link_index(link), physicsClientId=self.client)
        return [contact_point(point, self._names_of(point[2], point[4])) for point in points]

    def _names_of(self, body_id: int, index: int) -> tuple[str, str]:
        """(model, link) of a PyBullet body and link; "" for a body built outside a model (a heightfield)."""
        for body in self.bodies.values():
            if body.id == body_id:
                return body.name, next((name for name, i in body.links.items() if i == index), "")
        return "", ""

    def joint_wrench(self, model: str, joint: str) -> tuple[Vec3, Vec3, Vec3]:
        """(force, torque, point): what the parent applied to the child through `joint` in the last
        step, in the world frame, the torque about `point`, the child's centre of mass (where PyBullet
        reports it). Needs `measure_joint_wrench` first."""
        body = self.body(model)
        index = body.joint_index(joint)
        self._stepper.sync()
        reaction = pb.getJointState(body.id, index, physicsClientId=self.client)[2]
        com, orn = pb.getLinkState(body.id, index, computeForwardKinematics=True, physicsClientId=self.client)[:2]
        rotation = np.array(pb.getMatrixFromQuaternion(orn), dtype=float).reshape(3, 3)
        return vec3(matmul(rotation, reaction[:3])), vec3(matmul(rotation, reaction[3:])), vec3(com)

    def blind_rays_to(self, model: str) -> None:
        """Makes rays cast `blind_to` `model` pass through it and hit every other body (call it before
        stepping, as a sensor's setup does: PyBullet's cast gives the model a ray group of its own)."""
        self._rays.blind_to(self.body(model))

    def cast_rays(
        self, starts: npt.NDArray[np.float64], ends: npt.NDArray[np.float64], blind_to: str | None = None
    ) -> npt.NDArray[np.float64]:
        """Fraction of each ray (N×3 starts to N×3 ends) to its first hit, NaN where it hits nothing;
        the rays pass through the model `blind_to` (the sensor's own robot) and no other."""
        return self.cast_ray_batches([(starts, ends, blind_to)])[0]

    def cast_ray_batches(self, batches: Sequence[RayBatch], engine: bool = True) -> list[npt.NDArray[np.float64]]:
        """`cast_rays` of many sensors' rays in one cast (every lidar due in a step); `engine=False`
        casts through PyBullet even where the engine is on (the tests compare the two)."""
        bodies = [(starts, ends, self.body(blind) if blind is not None else None) for starts, ends, blind in batches]
        self._stepper.sync()  # the wheels' links where they turned to
        return self._rays.cast(bodies) if engine else self._rays.bullet.cast_all(bodies)


def _origin_velocities(
    linear: npt.NDArray[np.float64], angular: npt.NDArray[np.float64], offsets: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Each frame origin's velocity (N×3), v + ω × r: its centre of mass's `linear`, the body's
    `angular`, and `offsets` from that centre to the origin (products written out, no BLAS)."""
    (vx, vy, vz), (wx, wy, wz), (rx, ry, rz) = linear.T, angular.T, offsets.T
    return np.stack([vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx], axis=1)
