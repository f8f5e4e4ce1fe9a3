"""A render worker's copy of the server's scene: the same URDFs in its own PyBullet DIRECT client,
posed from each request. Both renderers draw from it: TinyRenderer through PyBullet itself, the
OpenGL renderer from its visual shapes and link poses."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from types import ModuleType

import numpy as np

from simbot.sim.render.specs import BodyState, SceneBody
from simbot.transform import Matrix, Transform, matmul, rigid_inverse


class BulletScene:
    """The bodies loaded as the server loaded them, posed on request; bodies come and go as the
    server's do (`add`, `remove`)."""

    def __init__(self, pb: ModuleType, bodies: Sequence[SceneBody] = ()) -> None:
        self.pb = pb
        self.client: int = pb.connect(pb.DIRECT)
        self.bodies: dict[str, SceneBody] = {}
        self.ids: dict[str, int] = {}
        self.movable: dict[str, tuple[tuple[int, str], ...]] = {}
        """Each body's joints that move: (index, name)."""
        self.inertial: dict[str, Transform] = {}
        """Each body's base centre of mass in its root link frame: PyBullet poses a base by it."""
        self.posed: dict[str, BodyState] | None = None
        """The states last applied."""
        self.version = 0
        """Counts the changes of pose and of bodies: what a renderer caches per pose is valid while it holds."""
        self.body_version = 0
        """Counts the changes of bodies (added, removed)."""
        for body in bodies:
            self.add(body)

    def add(self, body: SceneBody) -> None:
        """Loads `body` with the server's flags, so that base centre-of-mass frames agree."""
        pb = self.pb
        if body.name in self.ids:
            raise ValueError(f"body {body.name!r} is in the scene already")
        flags = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
        with tempfile.TemporaryDirectory(prefix="simbot-render-") as folder:
            path = os.path.join(folder, "body.urdf")
            with open(path, "w", encoding="utf-8") as file:
                file.write(body.urdf)
            try:
                body_id = pb.loadURDF(path, useFixedBase=body.static, flags=flags, physicsClientId=self.client)
            except pb.error as exc:
                raise RuntimeError(f"body {body.name!r}: {exc}") from None
        self.bodies[body.name] = body
        self.ids[body.name] = body_id
        info = pb.getDynamicsInfo(body_id, -1, physicsClientId=self.client)
        self.inertial[body.name] = Transform.of(info[3], info[4])
        self._place(body.name, body.base)
        self.movable[body.name] = self._one_dof_joints(body_id)
        self._changed()

    def edit(self, removed: Sequence[str], added: Sequence[SceneBody]) -> list[str]:
        """The bodies `removed` out and `added` in (`pipe.EditScene`); what failed, one line each (a
        body that does not load is left out, the rest applied). A body replaced by one of the same
        URDF keeps its PyBullet body: its description changed, not its links. Every body is then as
        a fresh load has it (at its start pose, its joints at zero), whatever was drawn before: what
        a renderer works out from the scene as loaded (the sun's view) is the same as a fresh one's."""
        replacing = {body.name: body for body in added}
        kept = set()
        for name in removed:
            body = replacing.get(name)
            if body is not None and name in self.bodies and body.urdf == self.bodies[name].urdf:
                self.bodies[name] = body
                kept.add(name)
            elif name in self.ids:
                self.remove(name)
        failures = []
        for body in added:
            if body.name in kept:
                continue
            try:
                self.add(body)
            except Exception as exc:  # noqa: BLE001 - reported to the pool, the rest of the edit goes on
                failures.append(f"add_body {body.name!r}: {type(exc).__name__}: {exc}")
        for name, body in self.bodies.items():
            self._place(name, body.base)
            for j, _ in self.movable[name]:
                self.pb.resetJointState(self.ids[name], j, 0.0, physicsClientId=self.client)
        self._changed()
        return failures

    def remove(self, name: str) -> None:
        """Takes the body out of the scene (a renderer that caches it drops it first)."""
        self.pb.removeBody(self.ids.pop(name), physicsClientId=self.client)
        for table in (self.bodies, self.movable, self.inertial):
            del table[name]
        self._changed()

    def _changed(self) -> None:
        """The set of bodies changed: the next request poses every body, whatever it held before
        (a body re-created under an old name must not pass for the old one's pose)."""
        self.posed = None
        self.version += 1
        self.body_version += 1

    def _place(self, name: str, root: Transform) -> None:
        """Puts the body's root link frame at `root` (PyBullet places a base by its centre of mass)."""
        pb, inertial = self.pb, self.inertial[name]
        com = pb.multiplyTransforms(root[0], root[1], inertial[0], inertial[1])
        pb.resetBasePositionAndOrientation(self.ids[name], *com, physicsClientId=self.client)

    def _one_dof_joints(self, body_id: int) -> tuple[tuple[int, str], ...]:
        pb = self.pb
        one_dof = (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC)
        count = pb.getNumJoints(body_id, physicsClientId=self.client)
        infos = [pb.getJointInfo(body_id, j, physicsClientId=self.client) for j in range(count)]
        return tuple((j, info[1].decode()) for j, info in enumerate(infos) if info[2] in one_dof)

    def apply(self, states: Mapping[str, BodyState]) -> None:
        """Put the moving bodies where the request says. The cameras of a set share one snapshot:
        the same states again cost nothing (and keep `version`, so link poses stay cached)."""
        if states == self.posed:
            return
        self.posed = None  # until every body is placed: a request that fails halfway leaves no valid pose
        self.version += 1
        pb, client = self.pb, self.client
        for name, state in states.items():
            body_id = self.ids[name]
            self._place(name, state.base)
            for j, joint in self.movable[name]:
                if joint not in state.joints:
                    raise ValueError(f"body {name!r}: no position for its joint {joint!r}")
                pb.resetJointState(body_id, j, state.joints[joint], physicsClientId=client)
        self.posed = dict(states)

    def link_matrices(self, name: str) -> dict[int, Matrix]:
        """World transform (4×4) of each URDF link frame of the body, -1 the base, as posed now."""
        pb, client, body_id = self.pb, self.client, self.ids[name]
        base = Transform.of(*pb.getBasePositionAndOrientation(body_id, physicsClientId=client)).matrix()
        inertial = Transform.of(*pb.getDynamicsInfo(body_id, -1, physicsClientId=client)[3:5]).matrix()
        frames = {-1: matmul(base, rigid_inverse(inertial))}  # the base pose is its centre of mass's
        count = pb.getNumJoints(body_id, physicsClientId=client)
        if count:
            states = pb.getLinkStates(
                body_id, list(range(count)), computeForwardKinematics=True, physicsClientId=client
            )
            frames.update((j, Transform.of(state[4], state[5]).matrix()) for j, state in enumerate(states))
        return frames

    def close(self) -> None:
        self.pb.disconnect(physicsClientId=self.client)


def view_matrix(pose: Transform) -> Matrix:
    """World → OpenGL eye coordinates for a camera that looks along its +x with z up (SDF)."""
    camera = Transform.of(*pose).matrix()
    # eye axes in the camera frame: x_eye = -y_cam (right), y_eye = z_cam (up), z_eye = -x_cam (back)
    eye_in_camera = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    return matmul(eye_in_camera, rigid_inverse(camera))


def projection_matrix(vfov_deg: float, aspect: float, near: float, far: float) -> Matrix:
    """OpenGL's perspective projection (gluPerspective), as PyBullet's computeProjectionMatrixFOV."""
    f = 1.0 / np.tan(np.radians(vfov_deg) / 2.0)
    return np.array(
        [
            [f / aspect, 0.0, 0.0, 0.0],
            [0.0, f, 0.0, 0.0],
            [0.0, 0.0, (far + near) / (near - far), 2.0 * far * near / (near - far)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )
