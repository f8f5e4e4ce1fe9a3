"""What systems change in the world, by name: joint and model commands (the Gazebo systems'
VelocityControl, ApplyJointForce, joint controllers, drives), teleports, and joints made and
unmade at run time. The `Physics` class's command half (`WorldCommands`); each is refused while
the world is read-only."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbot.sim.bullet import pb
from simbot.sim.physics.bullet_transforms import compose, invert, vec3
from simbot.sim.physics.guard import changes_world
from simbot.sim.physics.queries import Queries
from simbot.transform import Transform, Vec3, matmul

FIXED_CONSTRAINT_FORCE = 1e6
"""Newtons a detachable joint may exert: rigid for anything the tug can pull."""


class Commands(Queries):
    """Changing the world; the state it changes is `Physics`'s."""

    read_only: bool

    @changes_world
    def set_model_pose(self, model: str, pose: Transform) -> None:
        """Teleports the model frame to `pose` and stops it."""
        body = self.body(model)
        com = compose(pose, invert(body.com_to_frame))
        pb.resetBasePositionAndOrientation(body.id, *com, physicsClientId=self.client)
        pb.resetBaseVelocity(body.id, (0, 0, 0), (0, 0, 0), physicsClientId=self.client)
        self._stepper.moved([body.id])
        self._rays.moved([body])

    @changes_world
    def set_model_velocity(self, model: str, linear: Vec3, angular: Vec3) -> None:
        """Sets the model frame's velocity, both vectors given in the model frame (Gazebo's
        LinearVelocityCmd and AngularVelocityCmd): what VelocityControl commands before each step."""
        body = self.body(model)
        com = self._base(body)
        frame = compose(com, body.com_to_frame)
        rotation = np.reshape(pb.getMatrixFromQuaternion(frame[1]), (3, 3))
        angular_world = matmul(rotation, angular)
        linear_world = matmul(rotation, linear) + np.cross(angular_world, np.subtract(com[0], frame[0]))
        pb.resetBaseVelocity(body.id, vec3(linear_world), vec3(angular_world), physicsClientId=self.client)
        self._stepper.moved([body.id])

    @changes_world
    def set_joint_velocity(self, model: str, joint: str, velocity: float, max_effort: float) -> None:
        """Drives a joint at `velocity` with at most `max_effort` (N·m or N), as a velocity servo
        (a kinematic world turns it at `velocity`: see `stepping`)."""
        body = self.body(model)
        self._stepper.joint_velocity(body.id, body.joint_index(joint), velocity, max_effort)

    @changes_world
    def set_joint_positions(self, model: str, positions: Mapping[str, float]) -> None:
        """Puts joints at `positions` at rest, kinematically (an actor's legs as its skeleton has them)."""
        body = self.body(model)
        self._stepper.set_joint_positions(
            body.id, [body.joint_index(joint) for joint in positions], list(positions.values())
        )

    @changes_world
    def drive_base(self, model: str, forward: float, lateral: float, turn: float) -> None:
        """The planar twist a drive commands of the model frame (m/s along x and y, rad/s about z):
        in kinematic mode the base moves by it; a dynamic world moves it through the wheels instead."""
        self._stepper.drive(self.body(model), self.bodies.values(), forward, lateral, turn)

    @changes_world
    def set_joint_force(self, model: str, joint: str, force: float) -> None:
        """Applies `force` (N·m or N) on a joint for the next step only, as Gazebo's JointForceCmd:
        a controller commands it every step. The joint's friction motor keeps acting."""
        body = self.body(model)
        pb.setJointMotorControl2(
            body.id, body.joint_index(joint), pb.TORQUE_CONTROL, force=force, physicsClientId=self.client
        )

    @changes_world
    def apply_wrench(self, model: str, link: str, force: Vec3, torque: Vec3) -> None:
        """Pushes `link` for the next step only, as Gazebo's AddWorldWrench: `force` at its centre of
        mass and `torque`, both in the world frame (PyBullet clears external forces after each step)."""
        body_id, index, com = self._com_frame(model, link)
        pb.applyExternalForce(body_id, index, force, com[0], pb.WORLD_FRAME, physicsClientId=self.client)
        pb.applyExternalTorque(body_id, index, torque, pb.WORLD_FRAME, physicsClientId=self.client)

    @changes_world
    def measure_joint_wrench(self, model: str, joint: str) -> None:
        """Switches on PyBullet's reaction force sensor of a joint, which `joint_wrench` reads: a
        force/torque sensor asks for it when it is built, before the first step."""
        body = self.body(model)
        pb.enableJointForceTorqueSensor(body.id, body.joint_index(joint), True, physicsClientId=self.client)

    @changes_world
    def attach(self, parent: tuple[str, str], child: tuple[str, str]) -> int:
        """Fixes child (model, link) to parent (model, link) at their current relative pose; returns
        the joint's handle for `detach`."""
        pbody, plink, pcom = self._com_frame(*parent)
        cbody, clink, ccom = self._com_frame(*child)
        relative = compose(invert(pcom), ccom)
        cid = pb.createConstraint(
            pbody, plink, cbody, clink, pb.JOINT_FIXED, (0, 0, 0), relative[0], (0, 0, 0), relative[1], (0, 0, 0, 1),
            physicsClientId=self.client,
        )  # fmt: skip
        pb.changeConstraint(cid, maxForce=FIXED_CONSTRAINT_FORCE, physicsClientId=self.client)
        self.constraints[cid] = (parent[0], child[0])
        self._stepper.carry(cid, pbody, cbody)
        return cid

    def _com_frame(self, model: str, link: str) -> tuple[int, int, Transform]:
        """(body id, link index, the link's centre-of-mass frame in the world): PyBullet constrains those."""
        self._stepper.sync()
        body = self.body(model)
        index = body.link_index(link)
        if index == -1:
            return body.id, index, self._base(body)
        state = pb.getLinkState(body.id, index, physicsClientId=self.client)
        return body.id, index, Transform.of(state[0], state[1])

    @changes_world
    def detach(self, constraint: int) -> None:
        """Removes a joint made by `attach`."""
        if self.constraints.pop(constraint, None) is not None:
            pb.removeConstraint(constraint, physicsClientId=self.client)
            self._stepper.release(constraint)
