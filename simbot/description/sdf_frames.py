"""SDF poses and a model's frame graph: what every element with a `<pose>` is read with (models, actors).

A `<pose>` is six numbers x y z roll pitch yaw (radians, or degrees with `degrees="true"`) or, with
`rotation_format="quat_xyzw"`, seven; `relative_to` (or the older `frame`) names the frame it is in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from simbot.description.poses import IDENTITY, Pose
from simbot.description.xml import Element, Reader
from simbot.transform import Transform

MODEL_FRAME = "__model__"


def read_pose(reader: Reader, element: Element) -> tuple[Pose, str | None]:
    """The `<pose>` child of `element` and the frame it is relative to (None: the default)."""
    found = element.find("pose")
    if found is None:
        return IDENTITY, None
    relative_to = (found.get("relative_to") or found.get("frame") or "").strip() or None
    values = reader.floats(found)
    fmt = found.get("rotation_format", "euler_rpy")
    degrees = found.get("degrees", "false").lower() in ("1", "true")
    if not values:
        return IDENTITY, relative_to
    if fmt == "quat_xyzw" and len(values) == 7:
        return Pose.from_transform(Transform.of(values[:3], values[3:7])), relative_to
    if fmt != "euler_rpy" or len(values) != 6:
        raise reader.error(found, f"expected 6 numbers 'x y z roll pitch yaw', got {len(values)}")
    rpy = tuple(math.radians(v) if degrees else v for v in values[3:])
    return Pose(values[:3], rpy), relative_to  # type: ignore[arg-type]


@dataclass
class Frames:
    """The frame graph of one model: each frame's pose and the frame it is relative to."""

    reader: Reader
    edges: dict[str, tuple[Pose, str, Element]] = field(default_factory=dict)
    resolved: dict[str, Pose] = field(default_factory=lambda: {MODEL_FRAME: IDENTITY})

    def add(self, name: str, pose: Pose, relative_to: str, element: Element) -> None:
        if name in self.edges or name == MODEL_FRAME:
            raise self.reader.error(element, f"duplicate frame name {name!r} in this model")
        self.edges[name] = (pose, relative_to, element)

    def in_model(self, name: str, asked_by: Element, visiting: tuple[str, ...] = ()) -> Pose:
        """model_T_name, following relative_to links; unknown names and cycles are errors."""
        if name in self.resolved:
            return self.resolved[name]
        if name not in self.edges:
            raise self.reader.error(asked_by, f"unknown frame {name!r}")
        pose, parent, element = self.edges[name]
        if name in visiting:
            raise self.reader.error(element, f"frame {name!r} is defined relative to itself (cycle)")
        result = self.in_model(parent, element, visiting + (name,)) @ pose
        self.resolved[name] = result
        return result

    def in_link(self, link: str, element: Element, default: str | None = None) -> Pose:
        """The pose of `element` (a collision, visual or sensor) in the frame of `link`; its pose is
        relative to `default` (a joint's sensor: the joint) when it names no frame, else to the link."""
        pose, relative_to = read_pose(self.reader, element)
        relative_to = relative_to or default
        if relative_to is None or relative_to == link:
            return pose
        return self.in_model(link, element).inverse() @ self.in_model(relative_to, element) @ pose
