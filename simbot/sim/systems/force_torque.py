"""Force/torque sensor (SDF `force_torque`, a `<sensor>` of a `<joint>`): the wrench the joint transmits.

As Gazebo's: the force and torque between the joint's parent and child links, the torque about
the joint's origin, expressed in the orientation of the child link (default), the parent link or
the sensor, and by default as the child pushes on the parent (`child_to_parent`: a joint holding
a resting mass m reads m·g downwards); `parent_to_child` flips both. Then each axis' SDF noise
(mean, bias drawn per run, white σ). PyBullet measures a joint's reaction only when asked before
the first step, so the sensor switches that on when it is built (`Physics.measure_joint_wrench`).
Published as geometry_msgs/WrenchStamped in the sensor's frame on `<topic>` or Gazebo's
`world/<w>/model/<m>/joint/<j>/sensor/<s>/forcetorque`. A joint to the world is not a PyBullet
joint (the model's base is fixed instead) and cannot carry one.

SDF parameters (under `<force_torque>`; `ForceTorqueParams`):

| element | default | meaning |
| --- | --- | --- |
| `<frame>` | `child` | `child`, `parent` or `sensor`: whose orientation the wrench is expressed in |
| `<measure_direction>` | `child_to_parent` | or `parent_to_child`: which link's push is measured |
| `<force><x|y|z><noise>`, `<torque><x|y|z><noise>` | none | gaussian noise of each axis (N, N·m) |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbot.bus import messages
from simbot.description.model import Joint, Model, Sensor
from simbot.description.poses import Pose
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.transform import rotate_into

FRAMES = ("child", "parent", "sensor")
DIRECTIONS = ("child_to_parent", "parent_to_child")


@dataclass(frozen=True)
class ForceTorqueParams:
    """A force/torque sensor's SDF parameters (the table in the module docstring)."""

    frame: str = "child"
    measure_direction: str = "child_to_parent"
    noise: tuple[Noise, ...] = (Noise(),) * 6
    """force x y z, torque x y z."""

    @staticmethod
    def from_sdf(sensor: Sensor) -> ForceTorqueParams:
        element = SdfElement.of(sensor).child_or_empty("force_torque")
        frame = element.text("frame", "child") or "child"
        direction = element.text("measure_direction", "child_to_parent") or "child_to_parent"
        if frame not in FRAMES:
            raise element.error("frame", f"must be one of {', '.join(FRAMES)}, got {frame!r}")
        if direction not in DIRECTIONS:
            raise element.error("measure_direction", f"must be one of {', '.join(DIRECTIONS)}, got {direction!r}")
        noise = tuple(element.child_or_empty(kind).noise_of(axis) for kind in ("force", "torque") for axis in "xyz")
        return ForceTorqueParams(frame, direction, noise)


def _joint(model: Model | None, sensor: Sensor) -> Joint:
    joint = model.joint_of(sensor) if model is not None else None
    if joint is None:
        raise SystemConfigError(f"sensor {sensor.name}: a force_torque sensor belongs in a <joint>, not a <link>")
    if joint.parent == "world":
        raise SystemConfigError(
            f"sensor {sensor.name}: joint {joint.name!r} is to the world, which PyBullet fixes rather than joins"
        )
    return joint


class ForceTorque(FramedSensor):
    """geometry_msgs/WrenchStamped at the sensor's rate, stamped with the sim time of the sample."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = ForceTorqueParams.from_sdf(sensor)
        joint = _joint(ctx.model, sensor)
        super().__init__(ctx, self.params.noise, "forcetorque", messages.WrenchStamped)
        self._joint = joint.name
        self.physics.measure_joint_wrench(model, joint.name)
        self._origin = (model, link.name, link.pose.inverse() @ joint.pose)
        self._orientation = {
            "child": (model, link.name, Pose()),
            "parent": (model, joint.parent, Pose()),
            "sensor": self.where,
        }[self.params.frame]
        self._sign = -1.0 if self.params.measure_direction == "child_to_parent" else 1.0

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        force, torque_at_com, com = (np.asarray(v) for v in self.physics.joint_wrench(self.where[0], self._joint))
        origin = np.asarray(self.physics.frame_pose(*self._origin)[0])
        torque = torque_at_com + np.cross(com - origin, force)
        turn = self.physics.frame_pose(*self._orientation)[1]
        measured = self.noise(self._sign * np.array([*rotate_into(turn, force), *rotate_into(turn, torque)]))
        self.publish(info, messages.wrench_stamped(info.sim_time_ns, self.frame, measured[:3], measured[3:]))
