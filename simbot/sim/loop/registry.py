"""From an SDF `<plugin>` or `<sensor>` to a system class, through entry-point groups.

Plugins go through `simbot.systems`, keyed by canonical name; sensors through `simbot.sensors`,
keyed by the SDF sensor type (`gpu_lidar`, `ray`, `camera`, `imu`, ...).

Two more groups hold the systems that need no `<plugin>`: `simbot.world_systems`, which every
world gets, and `simbot.robot_systems`, which every described model gets.

Gazebo names one system several ways, which all reduce to one canonical name (`DiffDrive`,
simbot.description.naming.canonical_name): the entry point's name. simbot registers its own systems
in its pyproject.toml the same way a third party would in theirs.
"""

from __future__ import annotations

import logging
from functools import cache

from simbot.description.model import Plugin, Sensor
from simbot.description.naming import canonical_name
from simbot.plugins import load_group
from simbot.sim.loop.system import SystemFactory

log = logging.getLogger(__name__)

GROUP = "simbot.systems"
SENSOR_GROUP = "simbot.sensors"
WORLD_GROUP = "simbot.world_systems"
"""Systems every world gets without a `<plugin>` (the clock, ground-truth poses, camera rendering)."""
ROBOT_GROUP = "simbot.robot_systems"
"""Systems every described model gets (the robot, a namespaced model): its description and tf."""


@cache
def registered(group: str = GROUP) -> dict[str, SystemFactory]:
    """Name → system class, for every installed entry point of `group`."""
    return load_group(group)


def builtin(group: str) -> list[SystemFactory]:
    """Every system of a built-in group, in the order of their names (a fixed order, whatever installed them)."""
    systems = registered(group)
    return [systems[name] for name in sorted(systems)]


def lookup(plugin: Plugin) -> SystemFactory | None:
    """The class for `plugin`, or None with a warning naming it."""
    name = canonical_name(plugin)
    system = registered().get(name)
    if system is None:
        log.warning(
            "unknown plugin %s (%s): no system named %r is registered; ignored", plugin.name, plugin.filename, name
        )
    return system


def sensor_lookup(sensor: Sensor) -> SystemFactory | None:
    """The class for a `<sensor>` of this type, or None with a warning naming it."""
    system = registered(SENSOR_GROUP).get(sensor.type)
    if system is None:
        log.warning(
            "sensor %s of type %r: no sensor system of that type is registered; ignored", sensor.name, sensor.type
        )
    return system
