"""A zone server's keys: each robot's as one server has them, the world's own under the zone's name.

A fleet split into zones (`simbot-server --zone NAME:XMIN:XMAX`, docs/fleets.md) runs one world
in several servers on one bus namespace. Each robot's keys and frames stay under its own namespace
(`tug_7/cmd_vel`, `tug_7/base_link`), so they are the same whichever zone holds it; what each
zone's world publishes and serves of its own (its clock, world control, `tf` from `world` to each
robot's `odom`, ground truth on `model/<name>/pose`, `scene`, `map`) goes under NAME/, since the
zones' clocks and worlds' contents differ. Frames are not prefixed with the zone: `world` and
`tug_7/odom` are one tree across zones.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.sim.loop.bus_view import SimBus


@dataclass
class ZoneBus(SimBus):
    """The world's own view of the bus in zone `zone`: keys under the zone, frames as they are. The
    models' views (`scoped`) are plain ones, under their own namespaces."""

    zone: str = ""

    def topic(self, topic: str) -> str:
        return f"{self.zone}/{topic}"
