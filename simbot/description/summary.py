"""Plain-text tables of a model or world, for `simbot describe` and logs."""

from __future__ import annotations

import math
from collections.abc import Sequence

from simbot.description.model import (
    Axis,
    Box,
    Capsule,
    Cone,
    Cylinder,
    Ellipsoid,
    Geometry,
    Heightmap,
    Link,
    Model,
    Param,
    Plane,
    Plugin,
    Polyline,
    Sphere,
    World,
)
from simbot.description.poses import Pose


def table(title: str, headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A titled table with aligned columns; an empty table says so."""
    if not rows:
        return f"{title}: none"
    widths = [max(len(str(cell)) for cell in column) for column in zip(headers, *rows)]
    lines = [f"{title} ({len(rows)})", "  ".join(h.ljust(w) for h, w in zip(headers, widths)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    return "\n".join(lines)


def _num(value: float) -> str:
    return f"{value:.4g}" if math.isfinite(value) else str(value)


def _pose(pose: Pose) -> str:
    xyz = " ".join(_num(v + 0.0) for v in pose.xyz)
    rpy = " ".join(_num(v + 0.0) for v in pose.rpy)
    return f"{xyz} | {rpy}"


def _geometry(geometry: Geometry) -> str:
    if isinstance(geometry, Box | Plane):
        return f"{type(geometry).__name__.lower()} " + " x ".join(_num(v) for v in geometry.size)
    if isinstance(geometry, Cylinder | Capsule | Cone):
        return f"{type(geometry).__name__.lower()} r {_num(geometry.radius)} l {_num(geometry.length)}"
    if isinstance(geometry, Sphere):
        return f"sphere r {_num(geometry.radius)}"
    if isinstance(geometry, Ellipsoid):
        return "ellipsoid radii " + " ".join(_num(v) for v in geometry.radii)
    if isinstance(geometry, Polyline):
        return f"polyline {'+'.join(str(len(o)) for o in geometry.outlines)} points h {' '.join(_num(h) for h in geometry.heights)}"
    if isinstance(geometry, Heightmap):
        return f"heightmap {geometry.uri} " + " x ".join(_num(v) for v in geometry.size)
    return f"mesh {geometry.uri}"


def _limits(axis: Axis | None) -> str:
    if axis is None:
        return "-"
    span = "unlimited" if axis.lower is None or axis.upper is None else f"[{_num(axis.lower)}, {_num(axis.upper)}]"
    effort = "" if axis.effort is None else f" effort {_num(axis.effort)}"
    velocity = "" if axis.velocity is None else f" vel {_num(axis.velocity)}"
    return span + effort + velocity


def _param(param: Param) -> str:
    inner = param.text or ", ".join(_param(child) for child in param.children)
    return f"{param.tag}={inner}"


def _plugin_row(plugin: Plugin) -> list[str]:
    return [plugin.name, plugin.filename or "-", "; ".join(_param(p) for p in plugin.params) or "-"]


def _link_row(link: Link) -> list[str]:
    mass = "-" if link.inertial is None else _num(link.inertial.mass)
    shapes = ", ".join(_geometry(c.geometry) for c in link.collisions) or "-"
    return [link.name, _pose(link.pose), mass, shapes, str(len(link.visuals))]


def summarize_model(model: Model) -> str:
    """Links, joints, sensors and plugins of a model as tables."""
    head = f"model {model.name}" + (" (static)" if model.static else "") + f", canonical link {model.canonical_link}"
    if model.source is not None:
        head += f"\n  from {model.source}"
    links = table(
        "links",
        ["name", "pose in model: xyz | rpy", "mass", "collisions", "visuals"],
        [_link_row(link) for link in model.links],
    )
    joints = table(
        "joints",
        ["name", "type", "parent -> child", "axis", "limits"],
        [
            [
                j.name,
                j.type,
                f"{j.parent} -> {j.child}",
                " ".join(_num(v) for v in j.axis.xyz) if j.axis else "-",
                _limits(j.axis),
            ]
            for j in model.joints
        ],
    )
    sensors = table(
        "sensors",
        ["name", "type", "link", "rate Hz", "topic", "frame", "pose in link: xyz | rpy"],
        [
            [s.name, s.type, link.name, _num(s.update_rate), s.topic or "-", s.frame_name or "-", _pose(s.pose)]
            for link, s in model.sensors()
        ],
    )
    plugins = table("plugins", ["name", "filename", "parameters"], [_plugin_row(p) for p in model.plugins])
    return "\n\n".join([head, links, joints, sensors, plugins])


def summarize_world(world: World) -> str:
    """The world's settings and models; the dynamic models in full."""
    physics = world.physics
    head = (
        f"world {world.name}\n  from {world.source}\n"
        f"  physics: step {physics.max_step_size} s, real-time factor {physics.real_time_factor}, "
        f"gravity {' '.join(_num(g) for g in world.gravity)}, {len(world.lights)} lights"
    )
    models = table(
        "models",
        ["name", "pose: xyz | rpy", "static", "links", "from"],
        [
            [m.name, _pose(m.pose), "yes" if m.static else "no", str(len(m.links)), m.uri or "inline"]
            for m in world.models
        ],
    )
    plugins = table("world plugins", ["name", "filename", "parameters"], [_plugin_row(p) for p in world.plugins])
    dynamic = [summarize_model(m) for m in world.models if not m.static]
    return "\n\n".join([head, models, plugins, *dynamic])


def left_out_table(rows: Sequence[Sequence[str]]) -> str:
    """The systems a server would run this file's world without, for bad SDF parameters: (name, kind, reason) rows."""
    return table("systems left out (bad SDF parameters: a server runs without them)", ["name", "kind", "reason"], rows)


def summarize(description: Model | World) -> str:
    """The tables for whichever was loaded."""
    return summarize_world(description) if isinstance(description, World) else summarize_model(description)
