"""A message made of one array (an image, a depth map), its CDR written in place frame after frame.

The first frame's message is built and encoded through the encoder registry (`codec.ENCODERS`),
and where its stamp and its array's bytes lie in the encoding is found by encoding it again with
other ones; each later frame copies that encoding, writes its stamp there and copies the array's
bytes into it: one copy of the pixels where building a message and encoding it took three (a
render worker's cameras, simbot/sim/render/publishing.py). A builder whose bytes are not its
array's (none of simbot's) is checked once and built each frame, each such frame counted as the
registry's fall-back for its type.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.bus.codec import ENCODERS, encode

Build = Callable[[int, str, Any], Any]
"""(stamp ns, frame id, the output's array) → the message."""
STAMP = slice(4, 12)
"""builtin_interfaces/Time (int32 s, uint32 ns) right after the 4-byte CDR encapsulation: where
every message that starts with a std_msgs/Header keeps its stamp."""


class InPlace:
    """One product's CDR, written in place per frame; see the module docstring."""

    def __init__(self, build: Build, frame_id: str) -> None:
        self.build = build
        self.frame_id = frame_id
        self._encoded: bytes | None = None
        self._data: slice | None = None
        self._declined: str | None = None
        """Why the bytes cannot be written in place, once learnt so."""

    def encode(self, stamp_ns: int, array: npt.NDArray[Any]) -> bytes | bytearray:
        """The message of `array` under `stamp_ns`, as `encode(build(...))` gives it."""
        if self._encoded is not None and self._data is not None:
            out = bytearray(self._encoded)
            out[STAMP] = stamp_bytes(stamp_ns)
            out[self._data] = np.ascontiguousarray(array).reshape(-1).view(np.uint8).data
            return out
        msg = self.build(stamp_ns, self.frame_id, array)
        encoded = encode(msg)
        if self._declined is None:
            self._declined = self._learn(encoded, stamp_ns, array)
        if self._declined:
            ENCODERS.fell_back(msg.__msgtype__, f"{self.build.__name__}: {self._declined}")
        return encoded

    def _learn(self, encoded: bytes, stamp_ns: int, array: npt.NDArray[Any]) -> str:
        """Where the stamp and the array's bytes lie, kept only where writing them there gives the
        very encoding the builder gives; why not ("" where kept)."""
        raw = np.ascontiguousarray(array).reshape(-1).view(np.uint8)
        flipped = (~raw).view(array.dtype).reshape(array.shape)
        other = encode(self.build(stamp_ns, self.frame_id, flipped))
        differ = np.flatnonzero(np.frombuffer(encoded, np.uint8) != np.frombuffer(other, np.uint8))
        if (
            len(other) != len(encoded)
            or len(differ) != raw.size
            or (raw.size and differ[-1] - differ[0] + 1 != raw.size)
        ):
            return "its message's bytes are not its array's; built each frame"
        start = int(differ[0]) if raw.size else len(encoded)
        self._encoded, self._data = encoded, slice(start, start + raw.size)
        if bytes(self.encode(stamp_ns + 1, array)) != encode(self.build(stamp_ns + 1, self.frame_id, array)):
            self._encoded = self._data = None
            return "its stamp is not where a header keeps it; built each frame"
        return ""


def stamp_bytes(stamp_ns: int) -> bytes:
    """A stamp's 8 bytes as CDR writes builtin_interfaces/Time."""
    stamp = messages.time_msg(stamp_ns)
    return struct.pack("<iI", stamp.sec, stamp.nanosec)
