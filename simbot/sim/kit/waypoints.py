"""The waypoints a `<plugin>` states, as gz-sim's TrajectoryFollower reads them: listed (`<waypoints>`),
on a circle (`<circle>`) or along a line (`<line>`), in the world frame. TrajectoryFollower pushes a
model along them; SocialForce walks a person along them in place of its script.
"""

from __future__ import annotations

import math

from simbot.description.errors import SystemConfigError
from simbot.description.model import Param, Plugin
from simbot.transform import Transform, matmul, quaternion_to_matrix

CIRCLE_SAMPLES = 8
"""Waypoints of a `<circle>` (Gazebo's numSamples)."""


def _child(params: tuple[Param, ...], tag: str) -> Param | None:
    return next((p for p in params if p.tag == tag), None)


def _number(plugin: Plugin, block: Param, tag: str) -> float:
    found = _child(block.children, tag)
    if found is None:
        raise SystemConfigError(f"{plugin.name}: <{block.tag}><{tag}> is required")
    try:
        return float(found.text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{block.tag}><{tag}> expected a number, got {found.text!r}") from None


def waypoints(plugin: Plugin, start: Transform) -> list[tuple[float, float]]:
    """The waypoints the plugin states (`waypoints`, else `circle`, else `line`), in the world frame."""
    listed, circle, line = (_child(plugin.params, tag) for tag in ("waypoints", "circle", "line"))
    if listed is not None:
        points = []
        for point in (p for p in listed.children if p.tag == "waypoint"):
            values = point.text.split()
            try:
                x, y = (float(v) for v in values)
            except ValueError:
                raise SystemConfigError(f"{plugin.name}: <waypoint> expected 'x y', got {point.text!r}") from None
            points.append((x, y))
        if not points:
            raise SystemConfigError(f"{plugin.name}: <waypoints> holds no <waypoint>")
        return points
    x0, y0, _ = start.position
    if circle is not None:
        radius = _number(plugin, circle, "radius")
        angles = [2 * math.pi * i / CIRCLE_SAMPLES for i in range(CIRCLE_SAMPLES)]
        return [(x0 + radius * math.cos(a), y0 + radius * math.sin(a)) for a in angles]
    if line is not None:
        direction, length = _number(plugin, line, "direction"), _number(plugin, line, "length")
        step = (length * math.cos(direction), length * math.sin(direction), 0.0)
        end = matmul(quaternion_to_matrix(start.orientation), step)
        return [(x0, y0), (x0 + float(end[0]), y0 + float(end[1]))]
    return []
