"""The sim clock on `clock` (rosgraph_msgs/Clock), for ROS nodes running with use_sim_time."""

from __future__ import annotations

from simbot.bus import messages
from simbot.sim.system import Every, SystemContext

CLOCK_RATE = 100.0
"""Hz of sim time; SPEC §4 asks for at least 100."""


class ClockPublisher:
    """Built into the server; not from an SDF plugin."""

    def __init__(self, ctx: SystemContext) -> None:
        self._pub = ctx.bus.publisher("clock", messages.Clock)
        self._every = Every.hz(CLOCK_RATE)

    def post_update(self, now_ns: int) -> None:
        if self._every.due(now_ns):
            self._pub.put(messages.clock(now_ns))

    def reset(self, now_ns: int) -> None:
        self._every.restart()
