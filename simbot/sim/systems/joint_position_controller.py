"""JointPositionController: a joint held at the commanded position (Gazebo's JointPositionController).

| parameter | default |
|---|---|
| `joint_name` (repeatable: identical joints, driven alike) | required |
| `joint_index` (the axis; PyBullet's joints have one) | 0 |
| `topic` | `model/<model>/joint/<first joint_name>/<joint_index>/cmd_pos` |
| `sub_topic` | none; else the input is `model/<model>/<sub_topic>` |
| `initial_position` | 0 |
| `p_gain`, `i_gain`, `d_gain` | 1, 0.1, 0.01 |
| `i_max`, `i_min`, `cmd_max`, `cmd_min`, `cmd_offset` | 1, −1, 1000, −1000, 0 |
| `use_velocity_commands` | false |

Input: std_msgs/Float64, rad (m for a prismatic joint). The PID turns the first joint's position
error into a force on every joint, each step. With `use_velocity_commands` the PID is bypassed,
as in Gazebo: the joint is driven at the velocity that closes the error in one step, at most
`cmd_max` when the SDF states it. `use_actuator_msg` is refused (see JointController).
"""

from __future__ import annotations

from simbot.description.plugin_params import bool_param, number_param, param
from simbot.sim.kit.joints import CommandedJoints
from simbot.sim.kit.pid import Pid, PidGains
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


class JointPositionController:
    """Drives its joints toward the commanded position, by force (PID) or by velocity."""

    name = "JointPositionController"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        plugin = ctx.plugin
        if (param(plugin, "joint_index") or "0") != "0":
            raise SystemConfigError(f"{plugin.name}: <joint_index> must be 0: simbot's joints have one axis")
        self._joints = CommandedJoints(ctx, "JointPositionController", "0/cmd_pos", "initial_position")
        self._by_velocity = bool_param(plugin, "use_velocity_commands", default=False)
        self._max_speed = number_param(plugin, "cmd_max", positive=True) if self._by_velocity else None
        self._pid = Pid(PidGains.parse(plugin, 1.0, 0.1, 0.01))

    def pre_update(self, info: UpdateInfo) -> None:
        target = self._joints.update()
        dt = info.step_ns / 1e9
        error = self._joints.first()[0] - target
        if not self._by_velocity:
            self._joints.push(self._pid.update(error, dt))
            return
        speed = -error / dt
        if self._max_speed is not None:
            speed = min(max(speed, -self._max_speed), self._max_speed)
        self._joints.set_velocity(speed)

    def reset(self, info: UpdateInfo) -> None:
        self._joints.reset()
        self._pid.reset()
