"""The sim clock on `clock` (rosgraph_msgs/Clock), for ROS nodes running with use_sim_time."""

from __future__ import annotations

from simbot.bus import messages
from simbot.sim.kit.rates import Every
from simbot.sim.loop.system import LAST_PRIORITY, SystemContext, UpdateInfo

CLOCK_RATE = 100.0
"""Hz of sim time; SPEC §4 asks for at least 100."""


class ClockPublisher:
    """A world system (built in, no `<plugin>`). It publishes last in a step, so a client that
    sees sim time t has been sent everything stamped t."""

    name = "ClockPublisher"
    priority = LAST_PRIORITY

    def __init__(self, ctx: SystemContext) -> None:
        self._pub = ctx.bus.publisher("clock", messages.Clock)
        self._every = Every.hz(CLOCK_RATE)

    def post_update(self, info: UpdateInfo) -> None:
        if self._every.due(info.sim_time_ns):
            self._pub.put(messages.clock(info.sim_time_ns))

    def reset(self, info: UpdateInfo) -> None:
        self._every.restart()
