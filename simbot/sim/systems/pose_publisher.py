"""Ground truth: `model/<name>/pose` (geometry_msgs/PoseStamped in `world`) for every dynamic model
(a body `a::b`, a further joint tree of model `a`, on `model/a/b/pose`)."""

from __future__ import annotations

from simbot.bus import Publisher, messages
from simbot.description.naming import model_topic
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo

POSE_RATE = 50.0
"""Hz of sim time: as often as odometry, so the two can be compared sample by sample."""


class PosePublisher(Paced):
    """A world system (built in, no `<plugin>`): the poses of every model that is not static, from
    the step after it enters the world until it leaves."""

    name = "PosePublisher"

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        self._bus = ctx.bus
        self._pubs: dict[str, Publisher] = {}
        self.every = Every.hz(POSE_RATE)

    def model_added(self, event: ModelEvent) -> None:
        for name in event.bodies:
            if not self._physics.model_of(name).static:
                self._pubs[name] = self._bus.publisher(model_topic(name, "pose"), messages.PoseStamped)

    def model_removed(self, event: ModelEvent) -> None:
        for name in event.bodies:
            if (publisher := self._pubs.pop(name, None)) is not None:
                publisher.close()

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        if not self.every.due(now_ns):
            return
        for name, pub in self._pubs.items():
            if not pub.has_subscribers:
                continue
            xyz, quat = self._physics.model_pose(name)
            pub.put(messages.pose_stamped(now_ns, "world", xyz, quat))

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
