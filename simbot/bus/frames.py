"""Frame conventions shared by the server and the clients (REP-103, REP-105)."""

from __future__ import annotations

import math

OPTICAL_SUFFIX = "_optical_frame"
OPTICAL_RPY = (-math.pi / 2, 0.0, -math.pi / 2)
"""A camera's optical frame (z forward, x right, y down) in its body frame (x forward, z up)."""


def optical_frame(frame: str) -> str:
    """The optical frame of a camera whose body frame is `frame`; images are stamped in it."""
    return frame + OPTICAL_SUFFIX
