"""Ground truth: `model/<name>/pose` (geometry_msgs/PoseStamped in `world`) for every dynamic model
(a body `a::b`, a further joint tree of model `a`, on `model/a/b/pose`)."""

from __future__ import annotations

from simbot.bus import Publisher, messages
from simbot.sim.system import Every, SystemContext, UpdateInfo, model_topic

POSE_RATE = 50.0
"""Hz of sim time: as often as odometry, so the two can be compared sample by sample."""


class PosePublisher:
    """Built into the server for all models that are not static."""

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        self._bus = ctx.bus
        self._pubs: dict[str, Publisher] = {}
        self.track(list(ctx.physics.bodies))
        self._every = Every.hz(POSE_RATE)

    def track(self, bodies: list[str]) -> None:
        """Publishes the poses of these bodies (a created model's) from the next step, the static ones aside."""
        for name in bodies:
            if not self._physics.body(name).model.static:
                self._pubs[name] = self._bus.publisher(model_topic(name, "pose"), messages.PoseStamped)

    def untrack(self, bodies: list[str]) -> None:
        """A removed model's poses leave the bus."""
        for name in bodies:
            if (publisher := self._pubs.pop(name, None)) is not None:
                publisher.close()

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self._every.due(now_ns):
            return
        for name, pub in self._pubs.items():
            xyz, quat = self._physics.model_pose(name)
            pub.put(messages.pose_stamped(now_ns, "world", xyz, quat))

    def reset(self, info: UpdateInfo) -> None:
        self._every.restart()
