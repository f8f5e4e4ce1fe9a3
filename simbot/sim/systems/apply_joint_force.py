"""ApplyJointForce: a force (N) or torque (N·m) on one joint, held until the next command (Gazebo's ApplyJointForce).

| parameter | default |
|---|---|
| `joint_name` | required |

Input: `model/<model>/joint/<joint_name>/cmd_force` (std_msgs/Float64), Gazebo's key; the plugin
has no `<topic>`, as in Gazebo. The last command acts at every step from the next one on, on
the joint's one axis, as Gazebo applies `JointForceCmd[0]`; a reset returns it to zero.
"""

from __future__ import annotations

from simbot.description.naming import scoped_key
from simbot.sim.kit.drive import check_float, require_joints
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


class ApplyJointForce:
    """Applies the commanded force before every physics step."""

    name = "ApplyJointForce"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._name = ctx.require_model("ApplyJointForce")
        if len(ctx.plugin.get_all("joint_name")) > 1:
            raise SystemConfigError(f"{ctx.plugin.name}: <joint_name> names one joint, not several")
        self._joint = require_joints(ctx.plugin, model, "joint_name")[0]
        topic = ctx.model_topic(f"joint/{scoped_key(self._joint)}/cmd_force")
        self._commands = ctx.bus.input(topic, "std_msgs/msg/Float64", check_float)
        self._physics = ctx.physics
        self.force = 0.0

    def pre_update(self, info: UpdateInfo) -> None:
        for msg in self._commands.drain():
            self.force = msg.data
        if self.force:
            self._physics.set_joint_force(self._name, self._joint, self.force)

    def reset(self, info: UpdateInfo) -> None:
        self.force = 0.0
