"""What the joint systems share: the commanded joints of both joint controllers (JointController,
JointPositionController), which joints move (JointStatePublisher, RobotStatePublisher), and the
rate of the joints' state."""

from __future__ import annotations

from simbot.description.naming import scoped_key
from simbot.description.plugin_params import number_param
from simbot.sim.kit.drive import check_float, command_topic, joint_effort, refuse_actuators, require_joints
from simbot.sim.loop.system import SystemContext

MOVABLE = ("revolute", "continuous", "prismatic")
"""The joint types that move: those whose state is published."""
JOINT_STATE_RATE_HZ = 30.0
"""The joint-state rate (SPEC §1), at which the robot state publisher also sends the movable joints' tf."""


class CommandedJoints:
    """What both joint controllers share: the joints, their effort limits, the command input and its
    target (Gazebo's default key `model/<m>/joint/<first joint>/<leaf>`)."""

    def __init__(self, ctx: SystemContext, system: str, leaf: str, initial_tag: str) -> None:
        assert ctx.plugin is not None
        plugin = ctx.plugin
        model, self.model = ctx.require_model(system)
        refuse_actuators(plugin)
        self.joints = require_joints(plugin, model, "joint_name")
        self._efforts = [joint_effort(model, joint) for joint in self.joints]
        topic = command_topic(ctx, plugin, f"joint/{scoped_key(self.joints[0])}/{leaf}")
        self._commands = ctx.bus.input(topic, "std_msgs/msg/Float64", check_float)
        self._initial = number_param(plugin, initial_tag, default=0.0) or 0.0
        self._physics = ctx.physics
        self.target = self._initial

    def update(self) -> float:
        """The target after the commands that arrived."""
        for msg in self._commands.drain():
            self.target = msg.data
        return self.target

    def first(self) -> tuple[float, float, float]:
        """(position, velocity, effort) of the first joint, which the controller measures."""
        return self._physics.joint_states(self.model, [self.joints[0]])[0]

    def set_velocity(self, velocity: float) -> None:
        for joint, effort in zip(self.joints, self._efforts):
            self._physics.set_joint_velocity(self.model, joint, velocity, effort)

    def push(self, force: float) -> None:
        for joint in self.joints:
            self._physics.set_joint_force(self.model, joint, force)

    def reset(self) -> None:
        self.target = self._initial
