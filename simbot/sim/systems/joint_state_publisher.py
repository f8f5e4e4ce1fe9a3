"""JointStatePublisher: the position, velocity and effort of a model's joints as sensor_msgs/JointState.

| parameter | default |
|---|---|
| `joint_name` (repeatable) | every movable joint of the model |
| `topic` | `world/<world>/model/<model>/joint_state` (Gazebo's) |
| `update_rate` | 30 Hz (Gazebo's publishes every step) |
"""

from __future__ import annotations

from simbot.bus import messages
from simbot.description.naming import scoped_key
from simbot.description.plugin_params import number_param, param
from simbot.sim.kit.joints import JOINT_STATE_RATE_HZ, MOVABLE
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


class JointStatePublisher(Paced):
    """Publishes sensor_msgs/JointState at its rate, stamped with sim time."""

    name = "JointStatePublisher"

    def __init__(self, ctx: SystemContext) -> None:
        assert ctx.plugin is not None
        model, self._name = ctx.require_model("JointStatePublisher")
        names = ctx.plugin.get_all("joint_name") or [j.name for j in model.joints if j.type in MOVABLE]
        known = {j.name for j in model.joints if j.type in MOVABLE}
        for name in names:
            if name not in known:
                raise SystemConfigError(f"{ctx.plugin.name}: model {model.name!r} has no movable joint {name!r}")
        self._joints = list(names)
        self._physics = ctx.physics
        default = f"world/{scoped_key(ctx.world.name)}/{ctx.model_topic('joint_state')}"
        self._pub = ctx.bus.publisher(param(ctx.plugin, "topic") or default, messages.JointState)
        self.every = Every.hz(
            number_param(ctx.plugin, "update_rate", default=JOINT_STATE_RATE_HZ, positive=True) or JOINT_STATE_RATE_HZ
        )

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self.every.due(now_ns) or not self._pub.has_subscribers:
            return
        states = self._physics.joint_states(self._name, self._joints)
        self._pub.put(
            messages.joint_state(
                now_ns, self._joints, [s[0] for s in states], [s[1] for s in states], [s[2] for s in states]
            )
        )

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
