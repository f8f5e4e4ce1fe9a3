"""ROS 2 messages to CDR bytes and back, strictly.

CDR carries no type information, so a payload of the wrong type or a truncated one can only be
caught by its shape. `decode` is strict for that reason: it accepts only little-endian CDR (the
header `00 01`, as every ROS 2 middleware on x86 and ARM writes), turns every failure of the
deserializer into a `DecodeError`, and refuses payloads whose length is not what the decoded
message occupies (up to 7 trailing padding bytes allowed: middlewares pad to alignment). The
server relies on this to drop "a message of the wrong type" and "truncated CDR" with a counter
instead of acting on garbage.

The length check uses the number of bytes the deserializer consumed, which is exactly the length
the decoded message re-encodes to (CDR alignment is deterministic), without paying for a second
serialization of every camera image.
"""

from __future__ import annotations

from typing import Any

from rosbags.interfaces import Msgdef
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
CDR_LE = b"\x00\x01"
HEADER_SIZE = 4
MAX_PADDING = 7


class DecodeError(ValueError):
    """A payload that is not a valid CDR message of the expected type; str() is one line."""


class EncodeError(ValueError):
    """A message object that cannot be serialized (a field of the wrong type or out of range)."""


class UnknownMessageType(ValueError):
    """A type name that the ROS 2 Humble typestore does not know."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def message_type(typename: str) -> type[Any]:
    """The rosbags class of a ROS 2 type name such as `geometry_msgs/msg/Twist`."""
    try:
        return TYPESTORE.types[typename]
    except KeyError:
        raise UnknownMessageType(
            f"unknown ROS 2 message type {typename!r} (not in the ROS 2 Humble typestore)"
        ) from None


def _msgdef(typename: str) -> Msgdef[object]:
    message_type(typename)
    return TYPESTORE.get_msgdef(typename)


def encode(msg: Any) -> bytes:
    """CDR little-endian bytes with the 4-byte encapsulation header `00 01 00 00`."""
    typename = getattr(msg, "__msgtype__", None)
    if not isinstance(typename, str):
        raise EncodeError(f"cannot encode {type(msg).__name__}: not a rosbags message (no __msgtype__)")
    message_type(typename)
    try:
        return bytes(TYPESTORE.serialize_cdr(msg, typename, little_endian=True))
    except Exception as exc:  # rosbags raises struct.error, AttributeError, TypeError... for bad fields
        raise EncodeError(f"cannot encode {typename}: {_one_line(exc)}") from exc


def decode(data: bytes | bytearray | memoryview, typename: str) -> Any:
    """The message of type `typename` in `data`, or a DecodeError saying why not."""
    msgdef = _msgdef(typename)
    view = memoryview(data).cast("B")
    if len(view) < HEADER_SIZE:
        raise DecodeError(f"{typename}: {len(view)} bytes, shorter than the 4-byte CDR encapsulation header")
    if bytes(view[:2]) != CDR_LE:
        raise DecodeError(f"{typename}: encapsulation {bytes(view[:2]).hex(' ')} is not CDR little-endian (00 01)")
    try:
        message, size = msgdef.deserialize_cdr_le(view[HEADER_SIZE:], 0, msgdef.cls, TYPESTORE)
    except Exception as exc:  # anything rosbags raises on garbage: struct.error, UnicodeDecodeError, IndexError...
        raise DecodeError(f"{typename}: {_one_line(exc) or type(exc).__name__}") from exc
    trailing = len(view) - HEADER_SIZE - size
    if not 0 <= trailing <= MAX_PADDING:
        raise DecodeError(
            f"{typename}: payload of {len(view)} bytes but the message occupies {HEADER_SIZE + size} "
            f"({trailing} trailing bytes, at most {MAX_PADDING} allowed)"
        )
    return message
