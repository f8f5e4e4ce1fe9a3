"""A `<plugin>`'s parameters, read as Gazebo reads them: first of several tags, numbers, flags, priority.

The systems read their plugins with these, and so does every other reader of a system's parameters
(the typed ones: `drive_params`, `crowd_params`). A value that is unusable raises
`SystemConfigError` naming the plugin and the tag.
"""

from __future__ import annotations

import math

from simbot.description.errors import SystemConfigError
from simbot.description.model import Plugin
from simbot.description.xml import parse_flag


def param(plugin: Plugin, *tags: str, default: str | None = None) -> str | None:
    """The first of `tags` the plugin sets (Gazebo renamed several; the old names still work)."""
    for tag in tags:
        value = plugin.get(tag)
        if value is not None and value.strip() != "":
            return value.strip()
    return default


def number_param(plugin: Plugin, *tags: str, default: float | None = None, positive: bool = False) -> float | None:
    """A numeric parameter; a value that is not a (positive) number is an error naming it."""
    text = param(plugin, *tags)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{tags[0]}> expected a number, got {text!r}") from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise SystemConfigError(
            f"{plugin.name}: <{tags[0]}> must be a {'positive ' if positive else ''}finite number, got {text!r}"
        )
    return value


PRIORITY_TAGS = ("gz:system_priority", "gz::system_priority")
"""Where a `<plugin>` states its priority: Gazebo's element, written either way Gazebo accepts."""


def plugin_priority(plugin: Plugin) -> int | None:
    """The priority the SDF gives a plugin's system, if any; a value that is not an integer is an error naming it."""
    text = param(plugin, *PRIORITY_TAGS)
    if text is None:
        return None
    try:
        return int(text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{PRIORITY_TAGS[0]}> expected an integer, got {text!r}") from None


def bool_param(plugin: Plugin, *tags: str, default: bool) -> bool:
    """SDF booleans: true/false/1/0."""
    text = param(plugin, *tags)
    if text is None:
        return default
    flag = parse_flag(text)
    if flag is None:
        raise SystemConfigError(f"{plugin.name}: <{tags[0]}> expected true or false, got {text!r}")
    return flag
