"""Frame conventions shared by the server and the clients (REP-103, REP-105)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

OPTICAL_SUFFIX = "_optical_frame"
OPTICAL_RPY = (-math.pi / 2, 0.0, -math.pi / 2)
"""A camera's optical frame (z forward, x right, y down) in its body frame (x forward, z up)."""


def optical_frame(frame: str) -> str:
    """The optical frame of a camera whose body frame is `frame`; images are stamped in it."""
    return frame + OPTICAL_SUFFIX


SHARED_FRAMES = frozenset({"world", "map"})
"""Frames every robot shares: a model's namespace leaves them as they are."""


def prefixed_frame(frame: str, prefix: str) -> str:
    """`frame` in the tree of the robot under `prefix` (`tug_2/base_link`), as robot_state_publisher's
    frame_prefix does; shared, empty and already prefixed frames stay."""
    if not prefix or not frame or frame in SHARED_FRAMES or frame.startswith(prefix + "/"):
        return frame
    return f"{prefix}/{frame}"


def frame_prefix(frame: str) -> str:
    """The namespace of the robot whose tree holds `frame` (`tug_2` of `tug_2/base_scan_front`); empty for none."""
    return frame.rpartition("/")[0]


def with_frame_prefix(msg: Any, prefix: str) -> Any:
    """`msg` with its frame ids (header, child frame, each transform's) under `prefix`: one place for
    every system of a namespaced model, so none of them needs to know. A copy only where a frame
    changes: a system that names its frames prefixed already (`SimBus.frame`) costs no copy a message."""
    changes: dict[str, Any] = {}
    header = getattr(msg, "header", None)
    if header is not None:
        frame = prefixed_frame(header.frame_id, prefix)
        if frame != header.frame_id:
            changes["header"] = replace(header, frame_id=frame)
    child = getattr(msg, "child_frame_id", None)
    if isinstance(child, str) and prefixed_frame(child, prefix) != child:
        changes["child_frame_id"] = prefixed_frame(child, prefix)
    transforms = getattr(msg, "transforms", None)
    if isinstance(transforms, list):
        prefixed = [with_frame_prefix(t, prefix) for t in transforms]
        if any(new is not old for new, old in zip(prefixed, transforms)):
            changes["transforms"] = prefixed
    return replace(msg, **changes) if changes else msg
