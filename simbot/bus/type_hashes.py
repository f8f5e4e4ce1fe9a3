"""ROS 2 type hashes (REP-2011) of the types in simbot's typestore, for rmw_zenoh's key expressions.

Since ROS 2 Iron every type carries a hash of its definition, `RIHS01_<sha256 hex>`, and rmw_zenoh
writes it into each data key and liveliness token next to the type's DDS name: a subscriber whose
hash differs never matches the publisher. rosidl computes the hash at build time from the .msg and
.srv files (rosidl_generator_type_description); simbot has no ROS install, so it computes the same
description from the field definitions of codec.TYPESTORE, which hold the same messages.

The description is a JSON text of the type's fields and, sorted by name, of every type nested in it;
its exact shape (key order, separators) is part of the hash. Two spellings differ between rosbags
and rosidl: a .msg `char` is a uint8 to rosidl (rosbags keeps `char`), and an empty message has
rosidl's placeholder member. A service `pkg/srv/Name` is described as rosidl makes it up: a type of
three fields (request, response, event message) and the event message `pkg/srv/Name_Event`.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Nodetype

from simbot.bus.codec import TYPESTORE, UnknownMessageType

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Fielddefs, FieldDesc, NameDesc

NESTED = 1
BASE_TYPE_IDS = {
    "int8": 2,
    "uint8": 3,
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "float128": 12,
    "char": 3,  # a .msg char is rosidl's uint8 (FIELD_TYPE_CHAR, 13, is IDL's char)
    "wchar": 14,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "wstring": 18,
}
"""type_description_interfaces/msg/FieldType's ids of rosbags' base type names."""
BOUNDED_STRING_TYPE_IDS = {"string": 21, "wstring": 22}
ARRAY, BOUNDED_SEQUENCE, UNBOUNDED_SEQUENCE = 48, 96, 144
"""What a fixed-size array, a bounded and an unbounded sequence add to their element's type id."""

PLACEHOLDER: Fielddefs = [("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))]
EVENT_INFO = "service_msgs/msg/ServiceEventInfo"
TYPE_NAME = re.compile(r"(\w+)/(msg|srv)/(\w+)")
DDS_TYPE_NAME = re.compile(r"(\w+)::(msg|srv)::dds_::(\w+)_")


def dds_type_name(typename: str) -> str:
    """The DDS name of a ROS 2 type (`geometry_msgs/msg/Twist` -> `geometry_msgs::msg::dds_::Twist_`), as
    rmw_zenoh writes it in keys."""
    match = TYPE_NAME.fullmatch(typename)
    if match is None:
        raise ValueError(f"{typename!r} is not a ROS 2 type name such as geometry_msgs/msg/Twist")
    return f"{match[1]}::{match[2]}::dds_::{match[3]}_"


def ros_typename(dds_name: str) -> str | None:
    """The ROS 2 type name of a DDS type name read off a key, or None when the text is not one."""
    match = DDS_TYPE_NAME.fullmatch(dds_name)
    return f"{match[1]}/{match[2]}/{match[3]}" if match else None


@functools.cache
def type_hash(typename: str) -> str:
    """The RIHS01 hash of a message (`pkg/msg/Name`) or service (`pkg/srv/Name`) type, as rosidl computes it."""
    text = json.dumps(_description(typename), separators=(", ", ": "), ensure_ascii=True)
    return f"RIHS01_{hashlib.sha256(text.encode()).hexdigest()}"


def _description(typename: str) -> dict[str, Any]:
    """rosidl's TypeDescription: the type and every type nested in it at any depth, those sorted by name."""
    root = _struct(typename)
    referenced: dict[str, dict[str, Any]] = {}
    queue = _nested_names(root)
    while queue:
        name = queue.pop()
        if name not in referenced:
            referenced[name] = _struct(name)
            queue.extend(_nested_names(referenced[name]))
    return {"type_description": root, "referenced_type_descriptions": [referenced[n] for n in sorted(referenced)]}


def _nested_names(struct: dict[str, Any]) -> list[str]:
    return [field["type"]["nested_type_name"] for field in struct["fields"] if field["type"]["nested_type_name"]]


def _struct(typename: str) -> dict[str, Any]:
    return {"type_name": typename, "fields": [_field(name, desc) for name, desc in _fielddefs(typename)]}


def _fielddefs(typename: str) -> Fielddefs:
    """A registered message's fields, or those of the two types rosidl makes up for a service."""
    if typename in TYPESTORE.fielddefs:
        return TYPESTORE.fielddefs[typename][1] or PLACEHOLDER
    service = typename.removesuffix("_Event")
    if "/srv/" not in service or f"{service}_Request" not in TYPESTORE.fielddefs:
        raise UnknownMessageType(f"unknown ROS 2 type {typename!r}: neither a message nor a service of codec.TYPESTORE")
    if service != typename:
        request, response = _at_most_one(f"{service}_Request"), _at_most_one(f"{service}_Response")
        return [("info", _named(EVENT_INFO)), ("request", request), ("response", response)]
    return [
        ("request_message", _named(f"{service}_Request")),
        ("response_message", _named(f"{service}_Response")),
        ("event_message", _named(f"{service}_Event")),
    ]


def _named(typename: str) -> NameDesc:
    return (Nodetype.NAME, typename)


def _at_most_one(typename: str) -> FieldDesc:
    """The event's request or response: a sequence of at most one, empty when the event carries none."""
    return (Nodetype.SEQUENCE, (_named(typename), 1))


def _field(name: str, desc: FieldDesc) -> dict[str, Any]:
    """One field as type_description_interfaces/msg/Field, in the key order the hash depends on."""
    offset, capacity = 0, 0
    if desc[0] == Nodetype.ARRAY:
        offset, (desc, capacity) = ARRAY, desc[1]
    elif desc[0] == Nodetype.SEQUENCE:
        desc, capacity = desc[1]
        offset = BOUNDED_SEQUENCE if capacity else UNBOUNDED_SEQUENCE
    if desc[0] == Nodetype.NAME:
        type_id, string_capacity, nested = NESTED, 0, desc[1]
    else:
        base, string_capacity = desc[1]
        ids = BOUNDED_STRING_TYPE_IDS if string_capacity else BASE_TYPE_IDS
        type_id, nested = ids[base], ""
    return {
        "name": name,
        "type": {
            "type_id": type_id + offset,
            "capacity": capacity,
            "string_capacity": string_capacity,
            "nested_type_name": nested,
        },
    }
