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

from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Msgdef
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from simbot.bus.encoders import Encoders
from simbot.bus.fixed_cdr import WRITERS

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Typesdict

ROS_GZ_INTERFACES = {
    "ros_gz_interfaces/msg/Entity": """
uint8 NONE=0
uint8 LIGHT=1
uint8 MODEL=2
uint8 LINK=3
uint8 VISUAL=4
uint8 COLLISION=5
uint8 SENSOR=6
uint8 JOINT=7
uint64 id
string name
uint8 type
""",
    "ros_gz_interfaces/msg/JointWrench": """
std_msgs/Header header
std_msgs/String body_1_name
std_msgs/UInt32 body_1_id
std_msgs/String body_2_name
std_msgs/UInt32 body_2_id
geometry_msgs/Wrench body_1_wrench
geometry_msgs/Wrench body_2_wrench
""",
    "ros_gz_interfaces/msg/Contact": """
ros_gz_interfaces/Entity collision1
ros_gz_interfaces/Entity collision2
geometry_msgs/Vector3[] positions
geometry_msgs/Vector3[] normals
float64[] depths
ros_gz_interfaces/JointWrench[] wrenches
""",
    "ros_gz_interfaces/msg/Contacts": """
std_msgs/Header header
ros_gz_interfaces/Contact[] contacts
""",
    "ros_gz_interfaces/msg/Altimeter": """
std_msgs/Header header
float64 vertical_position
float64 vertical_velocity
float64 vertical_reference
""",
}
"""The messages of Gazebo's ROS 2 interface package (ros_gz_interfaces) that simbot publishes and
the ROS 2 Humble typestore lacks: field for field as the package defines them, so ros_gz_bridge's
subscribers read simbot's CDR unchanged."""

VISION_MSGS = {
    "vision_msgs/msg/Point2D": "float64 x\nfloat64 y\n",
    "vision_msgs/msg/Pose2D": "vision_msgs/Point2D position\nfloat64 theta\n",
    "vision_msgs/msg/BoundingBox2D": "vision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n",
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/Detection2D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox2D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection2DArray": "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n",
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection3DArray": "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n",
}
"""vision_msgs 4.x (the ROS 2 package of Humble and later) as far as the bounding-box camera
publishes it: Detection2DArray and Detection3DArray, as ros_gz_bridge maps Gazebo's annotated
boxes. Field for field as the package defines them; ROS 2 Humble's typestore lacks the package."""


STD_SRVS = {
    "std_srvs/srv/Empty_Request": "",
    "std_srvs/srv/Empty_Response": "",
    "std_srvs/srv/SetBool_Request": "bool data\n",
    "std_srvs/srv/SetBool_Response": "bool success\nstring message\n",
    "std_srvs/srv/Trigger_Request": "",
    "std_srvs/srv/Trigger_Response": "bool success\nstring message\n",
}
"""The request and response messages of the std_srvs services simbot serves (Empty, SetBool,
Trigger), field for field as the package's .srv files define them; an empty one gets rosidl's
placeholder member `structure_needs_at_least_one_member` from rosbags, as on the wire."""

SERVICE_MSGS = {
    "service_msgs/msg/ServiceEventInfo": """
uint8 REQUEST_SENT=0
uint8 REQUEST_RECEIVED=1
uint8 RESPONSE_SENT=2
uint8 RESPONSE_RECEIVED=3
uint8 event_type
builtin_interfaces/Time stamp
char[16] client_gid
int64 sequence_number
""",
}
"""The header of every service's event message (ROS 2 Iron and later), which a service's type hash
covers; ROS 2 Humble's typestore lacks the package."""


def _service_message(name: str, text: str) -> Typesdict:
    """A service's request or response under its own name: rosbags would file it under /msg/."""
    (definition,) = get_types_from_msg(text, name).values()
    return {name: definition}


def _typestore() -> Any:
    """ROS 2 Humble's message types, ros_gz_interfaces', vision_msgs' and the std_srvs services' (the one
    place types are registered)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    for name, text in (ROS_GZ_INTERFACES | VISION_MSGS | SERVICE_MSGS).items():
        store.register(get_types_from_msg(text, name))
    for name, text in STD_SRVS.items():
        store.register(_service_message(name, text))
    return store


TYPESTORE = _typestore()
CDR_LE = b"\x00\x01"
HEADER_SIZE = 4
MAX_PADDING = 7


class DecodeError(ValueError):
    """A payload that is not a valid CDR message of the expected type; str() is one line."""


class EncodeError(ValueError):
    """A message object that cannot be serialized (a field of the wrong type or out of range)."""


class UnknownMessageType(ValueError):
    """A type name that the typestore (ROS 2 Humble's and ros_gz_interfaces') does not know."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def message_type(typename: str) -> type[Any]:
    """The rosbags class of a ROS 2 type name such as `geometry_msgs/msg/Twist`."""
    try:
        return TYPESTORE.types[typename]
    except KeyError:
        raise UnknownMessageType(
            f"unknown ROS 2 message type {typename!r} (neither ROS 2 Humble's nor ros_gz_interfaces')"
        ) from None


def checked_typename(msgtype: type[Any] | str) -> str:
    """The ROS 2 type name of `msgtype` (a `messages` class or the name itself); an unknown one fails
    here, where the publisher is declared, not at its first put."""
    typename = msgtype if isinstance(msgtype, str) else msgtype.__msgtype__
    message_type(typename)
    return typename


def _msgdef(typename: str) -> Msgdef[object]:
    message_type(typename)
    return TYPESTORE.get_msgdef(typename)


def serialize(msg: Any, typename: str) -> bytes:
    """rosbags' generic serializer: every type, and the errors of bad fields as EncodeError."""
    message_type(typename)
    try:
        return bytes(TYPESTORE.serialize_cdr(msg, typename, little_endian=True))
    except Exception as exc:  # rosbags raises struct.error, AttributeError, TypeError... for bad fields
        raise EncodeError(f"cannot encode {typename}: {_one_line(exc)}") from exc


ENCODERS = Encoders(WRITERS, serialize)
"""simbot's one encoder registry (`encoders`): the fixed layouts the server publishes at high rates
(fixed_cdr), rosbags for the rest and for what they decline."""


def encode(msg: Any) -> bytes:
    """CDR little-endian bytes with the 4-byte encapsulation header `00 01 00 00`, through `ENCODERS`:
    the fixed-layout types are written by fixed_cdr, byte for byte as rosbags would."""
    typename = getattr(msg, "__msgtype__", None)
    if not isinstance(typename, str):
        raise EncodeError(f"cannot encode {type(msg).__name__}: not a rosbags message (no __msgtype__)")
    return ENCODERS.encode(msg, typename)


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
