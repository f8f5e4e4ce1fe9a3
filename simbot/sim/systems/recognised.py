"""Gazebo world systems that simbot's own loop already covers (SPEC §2): recognised, no action."""

from __future__ import annotations

import logging

from simbot.sim.loop.system import SystemContext

log = logging.getLogger(__name__)


class Recognised:
    """Physics, Sensors, Imu, SceneBroadcaster, UserCommands, Contact: the server does their job."""

    name = "Recognised"

    def __init__(self, ctx: SystemContext) -> None:
        if ctx.plugin is not None:
            log.debug("%s: provided by the simbot server itself", ctx.plugin.name)
