"""The one road from a message to its CDR bytes, and the count of where it left its fast lane.

Every CDR simbot writes goes through one `Encoders` (`codec.ENCODERS`): the bus's publishers and
services through `codec.encode`, a render worker's images through `in_place.InPlace`. rosbags'
generic serializer writes any type; a few types have a faster writer that gives the very same
bytes:

- a fixed layout, one `struct.pack` (`fixed_cdr`: Imu, Odometry, TFMessage, Clock, LaserScan,
  which the server publishes thousands of times a sim second with a fleet);
- in place (`in_place`: an image's encoding learnt from its first frame, its stamp and pixels
  rewritten each frame).

A faster writer declines what it cannot write as rosbags would (an array of another dtype, a
field struct refuses): the message then goes to rosbags, which writes the same bytes or raises the
error it always raised. Each such fall-back is counted per type (`fallbacks`) and the first of each
type is logged with why, so that a regression in a fast writer shows as a warning and a count, not
as a silent slowdown; tests/test_bus_cdr_fast.py fails when one of the server's hot types falls back.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any

log = logging.getLogger(__name__)

Writer = Callable[[Any], bytes]
"""A fast writer: a message's CDR bytes, encapsulation header included, or an exception when it declines."""
Serialize = Callable[[Any, str], bytes]
"""The generic writer: (message, its type name) → its CDR bytes, or EncodeError."""


class Encoders:
    """The writers of CDR by type name: a fast one where a type has it, the generic one for the
    rest and for what a fast one declines; fall-backs counted per type."""

    def __init__(self, fast: Mapping[str, Writer], generic: Serialize) -> None:
        self._fast = dict(fast)
        self._generic = generic
        self._fallbacks: dict[str, int] = {}
        self._lock = threading.Lock()  # publishers encode on several threads; only a fall-back takes it

    def encode(self, msg: Any, typename: str) -> bytes:
        """`msg`'s CDR bytes (encapsulation header included) by the fastest writer that takes it."""
        fast = self.fast(msg, typename)
        return fast if fast is not None else self._generic(msg, typename)

    def fast(self, msg: Any, typename: str) -> bytes | None:
        """`msg`'s bytes by its type's fixed-layout writer; None where it has none or that writer
        declines (then counted: the generic writer is the caller's to call)."""
        writer = self._fast.get(typename)
        if writer is None:
            return None
        try:
            return writer(msg)
        except (
            Exception
        ) as exc:  # Unusual, struct.error, AttributeError, UnicodeEncodeError...: rosbags' to write or word
            self.fell_back(typename, f"{type(exc).__name__}: {exc}")
            return None

    def fell_back(self, typename: str, why: str) -> None:
        """Counts one message of `typename` written by the generic writer where a faster one was
        meant to; the first of each type is logged with `why`."""
        with self._lock:
            count = self._fallbacks[typename] = self._fallbacks.get(typename, 0) + 1
        if count == 1:
            log.warning(
                "%s: written by rosbags' generic serializer, not its faster writer (%s); further ones counted only",
                typename,
                why,
            )

    def fallbacks(self) -> dict[str, int]:
        """How many messages of each type fell back to the generic writer so far in this process."""
        with self._lock:
            return dict(self._fallbacks)
