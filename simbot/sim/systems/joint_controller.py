"""JointController: a joint's velocity as commanded (Gazebo's JointController).

| parameter | default |
|---|---|
| `joint_name` (repeatable: identical joints, driven alike) | required |
| `topic` | `model/<model>/joint/<first joint_name>/cmd_vel` |
| `sub_topic` | none; else the input is `model/<model>/<sub_topic>` |
| `initial_velocity` | 0 |
| `use_force_commands` | false |
| `p_gain`, `i_gain`, `d_gain` (force mode) | 1, 0, 0 |
| `i_max`, `i_min`, `cmd_max`, `cmd_min`, `cmd_offset` (force mode) | 1, −1, 1000, −1000, 0 |
| `disable_braking` (force mode) | false |

Input: std_msgs/Float64, rad/s (m/s for a prismatic joint). Velocity mode commands the velocity
directly, as Gazebo's JointVelocityCmd, with at most the joint's SDF effort. Force mode applies
a PID's force on the error of the first joint's velocity to every joint; with `disable_braking`
the joint coasts while it runs faster than commanded in the commanded direction.
`use_actuator_msg` (gz.msgs.Actuators) has no ROS 2 message here and is refused.
"""

from __future__ import annotations

import math

from simbot.sim.system import SystemConfigError, SystemContext, UpdateInfo, bool_param, number_param, scoped_key
from simbot.sim.systems.drive import check_float, command_topic, joint_effort, require_joints
from simbot.sim.systems.pid import Pid, PidGains


def refuse_actuators(ctx: SystemContext) -> None:
    """Gazebo's `use_actuator_msg` takes gz.msgs.Actuators, which has no ROS 2 counterpart."""
    assert ctx.plugin is not None
    if bool_param(ctx.plugin, "use_actuator_msg", default=False):
        raise SystemConfigError(
            f"{ctx.plugin.name}: <use_actuator_msg> is not supported (gz.msgs.Actuators is no ROS 2 message)"
        )


class JointController:
    """Holds the commanded velocity on its joints, directly or through a PID on force."""

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        plugin = ctx.plugin
        model, self._name = ctx.require_model("JointController")
        refuse_actuators(ctx)
        self._joints = require_joints(plugin, model, "joint_name")
        self._efforts = [joint_effort(model, joint) for joint in self._joints]
        topic = command_topic(ctx, plugin, f"joint/{scoped_key(self._joints[0])}/cmd_vel")
        self._commands = ctx.bus.input(topic, "std_msgs/msg/Float64", check_float)
        self._initial = number_param(plugin, "initial_velocity", default=0.0) or 0.0
        self._force_mode = bool_param(plugin, "use_force_commands", default=False)
        self._no_braking = bool_param(plugin, "disable_braking", default=False)
        self._pid = Pid(PidGains.parse(plugin, 1.0, 0.0, 0.0))
        self._physics = ctx.physics
        self.target = self._initial

    def pre_update(self, info: UpdateInfo) -> None:
        for msg in self._commands.drain():
            self.target = msg.data
        if self._force_mode:
            self._push(info.step_ns / 1e9)
            return
        for joint, effort in zip(self._joints, self._efforts):
            self._physics.set_joint_velocity(self._name, joint, self.target, effort)

    def _push(self, dt: float) -> None:
        error = self._physics.joint_states(self._name, [self._joints[0]])[0][1] - self.target
        if self._no_braking and (self.target == 0.0 or math.copysign(1.0, self.target) * error > 0.0):
            return
        force = self._pid.update(error, dt)
        for joint in self._joints:
            self._physics.set_joint_force(self._name, joint, force)

    def reset(self, info: UpdateInfo) -> None:
        self.target = self._initial
        self._pid.reset()
