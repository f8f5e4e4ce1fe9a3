"""VelocityControl: a model moved at the commanded twist, whatever pushes it (Gazebo's VelocityControl).

| parameter | default |
|---|---|
| `topic` | `model/<model>/cmd_vel` |
| `initial_linear` | 0 0 0 (m/s, model frame) |
| `initial_angular` | 0 0 0 (rad/s, model frame) |

Input: geometry_msgs/Twist in the model frame. Before every step the model frame's velocity is
set to it, as Gazebo sets LinearVelocityCmd and AngularVelocityCmd: contacts and gravity act
within the step and are undone at the next (a commanded z of 0 sinks a model by g·dt² a step
where nothing holds it). Gazebo's per-link commands (`<link_name>`) are not supported.
"""

from __future__ import annotations

from simbot.description.plugin_params import param
from simbot.sim.kit.drive import check_twist, vector_param
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


class VelocityControl:
    """Sets the model's velocity to the last command before each physics step."""

    name = "VelocityControl"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        _, self._name = ctx.require_model("VelocityControl")
        if param(ctx.plugin, "link_name") is not None:
            raise SystemConfigError(f"{ctx.plugin.name}: <link_name> (per-link velocity) is not supported")
        self._initial = (vector_param(ctx.plugin, "initial_linear"), vector_param(ctx.plugin, "initial_angular"))
        self._commands = ctx.bus.input(
            param(ctx.plugin, "topic") or ctx.model_topic("cmd_vel"), "geometry_msgs/msg/Twist", check_twist
        )
        self._physics = ctx.physics
        self.linear, self.angular = self._initial

    def pre_update(self, info: UpdateInfo) -> None:
        for msg in self._commands.drain():
            self.linear = (msg.linear.x, msg.linear.y, msg.linear.z)
            self.angular = (msg.angular.x, msg.angular.y, msg.angular.z)
        self._physics.set_model_velocity(self._name, self.linear, self.angular)

    def reset(self, info: UpdateInfo) -> None:
        self.linear, self.angular = self._initial
