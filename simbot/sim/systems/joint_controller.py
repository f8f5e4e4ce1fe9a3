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

from simbot.description.plugin_params import bool_param
from simbot.sim.kit.joints import CommandedJoints
from simbot.sim.kit.pid import Pid, PidGains
from simbot.sim.loop.system import SystemContext, UpdateInfo


class JointController:
    """Holds the commanded velocity on its joints, directly or through a PID on force."""

    name = "JointController"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        self._joints = CommandedJoints(ctx, "JointController", "cmd_vel", "initial_velocity")
        self._force_mode = bool_param(ctx.plugin, "use_force_commands", default=False)
        self._no_braking = bool_param(ctx.plugin, "disable_braking", default=False)
        self._pid = Pid(PidGains.parse(ctx.plugin, 1.0, 0.0, 0.0))

    def pre_update(self, info: UpdateInfo) -> None:
        target = self._joints.update()
        if not self._force_mode:
            self._joints.set_velocity(target)
            return
        error = self._joints.first()[1] - target
        if self._no_braking and (target == 0.0 or math.copysign(1.0, target) * error > 0.0):
            return
        self._joints.push(self._pid.update(error, info.step_ns / 1e9))

    def reset(self, info: UpdateInfo) -> None:
        self._joints.reset()
        self._pid.reset()
