"""What SDF says of a body's dynamics that PyBullet's URDF loader does not take: passive joints
with their friction, μ per link, anisotropic wheel friction with a tyre's compliance, castors that
pass no friction, and no velocity damping."""

from __future__ import annotations

import math

import numpy as np

from simbot.description.model import Joint, Model
from simbot.description.poses import IDENTITY, Pose
from simbot.description.urdf_writer import sdf_joint
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Body
from simbot.sim.physics.tyre import Tyre
from simbot.sim.physics.wheel_friction import TYRE_STIFFNESS, Wheel, WheelFriction
from simbot.transform import Vec3, matmul, norm

SDF_DEFAULT_MU = 1.0
"""SDF's friction default. PyBullet multiplies two surfaces' coefficients, so with 1.0 on every
surface that states none, a pair where one side states μ behaves as ODE's min(μ1, μ2)."""


def configure(client: int, body: Body) -> WheelFriction | None:
    """Sets a loaded body's dynamics as its SDF states them; returns its wheels' friction model, if it has wheels."""
    _configure_joints(client, body)
    wheels = _configure_friction(client, body)
    _undamp(client, body)
    _configure_castors(client, body)
    return wheels


def _configure_joints(client: int, body: Body) -> None:
    """PyBullet puts a velocity motor on every joint; SDF joints are passive until a system drives them."""
    sdf_joints = {joint.name: joint for joint in body.model.joints}
    for urdf_name, index in body.joints.items():
        joint = sdf_joints.get(sdf_joint(urdf_name))
        if joint is not None:
            friction = joint.axis.friction if joint.axis else 0.0
            pb.setJointMotorControl2(body.id, index, pb.VELOCITY_CONTROL, force=friction, physicsClientId=client)


def _configure_friction(client: int, body: Body) -> WheelFriction | None:
    """SDF μ per link; wheels with μ ≠ μ2 get the anisotropic model PyBullet lacks (see wheel_friction).
    A merged link's collisions take their host's μ (the tug's castors, the chassis's)."""
    wheels = []
    for link in body.model.links:
        index = body.links.get(link.name)
        if index is None or body.hosts[link.name] != link.name:
            continue
        friction = next((c.friction for c in link.collisions if c.friction is not None), None)
        mu = friction.mu if friction else SDF_DEFAULT_MU
        joint = _wheel_joint(body.model, link.name) if friction and friction.mu != friction.mu2 else None
        if friction and joint is not None and joint.axis is not None:
            fdir1 = _fdir1_angle(body.model, joint, friction.fdir1)
            wheels.append(Wheel(index, Tyre.of(friction), _axis_in_link(joint, link.pose), fdir1))
            mu = 0.0
        pb.changeDynamics(
            body.id, index, lateralFriction=mu, rollingFriction=0, spinningFriction=0, physicsClientId=client
        )
    if not wheels:
        return None
    _soften_tyres(client, body, wheels)
    step = pb.getPhysicsEngineParameters(physicsClientId=client)["fixedTimeStep"]
    return WheelFriction(client, body.id, tuple(wheels), step)


def _soften_tyres(client: int, body: Body, wheels: list[Wheel]) -> None:
    """Tyre compliance, critically damped for each wheel's share of the body's mass."""
    mass = sum(pb.getDynamicsInfo(body.id, i, physicsClientId=client)[0] for i in body.indices)
    damping = 2.0 * math.sqrt(TYRE_STIFFNESS * mass / len(wheels))
    for wheel in wheels:
        pb.changeDynamics(
            body.id, wheel.link, contactStiffness=TYRE_STIFFNESS, contactDamping=damping, physicsClientId=client
        )


def _undamp(client: int, body: Body) -> None:
    """No velocity damping: SDF states none, and Gazebo applies none. PyBullet's default (0.04
    linear and quadratic) takes 8 % of a joint's speed after 1 s at 5 rad/s, so a torque would
    not accelerate a link as τ/I predicts."""
    pb.changeDynamics(body.id, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)


def _configure_castors(client: int, body: Body) -> None:
    """A ball castor's sphere passes no friction (an ideal castor's ball spins instead, and so must
    a fixed one) and makes no contact until it touches: hanging 2 cm up, within Bullet's 2 cm
    contact margin, it would otherwise put 8 idle contacts per tug into the solver every step.
    A castor merged into its host (`Physics.merge_fixed_links`) is the host's to configure."""
    for joint in body.model.joints:
        if joint.name in body.castors and body.hosts[joint.child] == joint.child:
            pb.changeDynamics(
                body.id,
                body.links[joint.child],
                lateralFriction=0.0,
                contactProcessingThreshold=0.0,
                physicsClientId=client,
            )


def _wheel_joint(model: Model, link: str) -> Joint | None:
    return next((j for j in model.joints if j.child == link and j.type in ("revolute", "continuous")), None)


def _fdir1_angle(model: Model, joint: Joint, fdir1: Vec3 | None) -> float:
    """SDF's fdir1 of a wheel as its angle from the rolling direction on level ground. fdir1 is
    read in the frame of the wheel joint's parent link (the chassis), where Gazebo's mecanum
    example states it with `gz:expressed_in`: the wheel's own frame spins."""
    if fdir1 is None or joint.axis is None:
        return 0.0
    up = np.array([0.0, 0.0, 1.0])
    axle = matmul(joint.pose.matrix()[:3, :3], joint.axis.xyz)
    along = np.cross(axle, up)
    if norm(along) < 1e-9:
        return 0.0
    across = np.cross(up, along)
    parent = next((link.pose for link in model.links if link.name == joint.parent), IDENTITY)
    direction = matmul(parent.matrix()[:3, :3], fdir1)
    return math.atan2(float(matmul(direction, across)), float(matmul(direction, along)))


def _axis_in_link(joint: Joint, link_pose: Pose) -> Vec3:
    """A joint's axis (given in the joint frame) in its child link's frame; both poses are in the model frame."""
    assert joint.axis is not None
    rotation = (link_pose.inverse() @ joint.pose).matrix()[:3, :3]
    x, y, z = matmul(rotation, joint.axis.xyz)
    return float(x), float(y), float(z)
