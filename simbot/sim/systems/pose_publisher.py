"""Ground truth: `model/<name>/pose` (geometry_msgs/PoseStamped in `world`) for every dynamic model
(a body `a::b`, a further joint tree of model `a`, on `model/a/b/pose`)."""

from __future__ import annotations

from simbot.bus import messages
from simbot.sim.system import Every, SystemContext, UpdateInfo, model_topic

POSE_RATE = 50.0
"""Hz of sim time: as often as odometry, so the two can be compared sample by sample."""


class PosePublisher:
    """Built into the server for all models that are not static."""

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        dynamic = [name for name, body in ctx.physics.bodies.items() if not body.model.static]
        self._pubs = {name: ctx.bus.publisher(model_topic(name, "pose"), messages.PoseStamped) for name in dynamic}
        self._every = Every.hz(POSE_RATE)

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self._every.due(now_ns):
            return
        for name, pub in self._pubs.items():
            xyz, quat = self._physics.model_pose(name)
            pub.put(messages.pose_stamped(now_ns, "world", xyz, quat))

    def reset(self, info: UpdateInfo) -> None:
        self._every.restart()
