"""rmw_zenoh's wire format: the keys, attachments and graph tokens a ROS 2 node on Zenoh expects.

With `RMW_IMPLEMENTATION=rmw_zenoh_cpp`, a ROS 2 node finds simbot's topics without a bridge
because simbot writes exactly what rmw_zenoh writes (its design document, `docs/design.md` in
ros2/rmw_zenoh, and its code):

- data on `<domain>/<topic>/<DDS type>/<type hash>`: `0/ns/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_…`
  (the topic's fully qualified name without its leading slash; Humble writes
  `TypeHashNotSupported` for the hash);
- every sample with a 33-byte attachment: sequence number and source timestamp (int64 each,
  little-endian), then the publisher's 16-byte GID behind its length byte;
- each node, publisher, subscriber and service announced by a liveliness token
  `@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<NN|MP|MS|SS>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`,
  names with `/` written as `%`.
"""

from __future__ import annotations

import os
import struct
import threading
import time
from dataclasses import dataclass
from typing import Literal

from simbot.bus.type_hashes import dds_type_name, type_hash

DISTROS = ("humble", "jazzy", "kilted", "lyrical", "rolling")
DEFAULT_DISTRO = "jazzy"
"""The LTS rmw_zenoh ships binaries for; kilted, lyrical and rolling write the same format."""
NO_HASH = "TypeHashNotSupported"
"""What Humble's rmw_zenoh writes where later distros write a type hash (REP-2011 came with Iron)."""
ADMIN_SPACE = "@ros2_lv"
ENCLAVE = "%"
GID_SIZE = 16
ATTACHMENT = struct.Struct(f"<qqB{GID_SIZE}s")
"""Sequence number, source timestamp, the GID's length (16) and the GID: 33 bytes, as Jazzy ≥ 0.2.4 writes."""

EntityKind = Literal["MP", "MS", "SS"]
"""Publisher, subscriber, service server (`NN` is the node itself)."""


class AttachmentError(ValueError):
    """A sample's attachment that is not rmw_zenoh's; str() is one line."""


@dataclass(frozen=True)
class RosGraph:
    """Where on the ROS 2 graph a node's keys and tokens go: the domain, and the distro's format."""

    domain_id: int = 0
    distro: str = DEFAULT_DISTRO

    def __post_init__(self) -> None:
        if self.distro not in DISTROS:
            raise ValueError(f"--ros-distro {self.distro!r}: one of {', '.join(DISTROS)}")
        if not 0 <= self.domain_id <= 232:
            raise ValueError(f"ROS_DOMAIN_ID {self.domain_id}: a number from 0 to 232")

    def hash_of(self, typename: str) -> str:
        """The type hash a key and a token carry for `typename` in this distro."""
        return NO_HASH if self.distro == "humble" else type_hash(typename)

    def data_key(self, name: str, typename: str) -> str:
        """The key of topic (or service) `name` (no leading slash) carrying `typename`."""
        return f"{self.domain_id}/{name}/{dds_type_name(typename)}/{self.hash_of(typename)}"

    def any_type_key(self, name: str) -> str:
        """Every key of topic `name`, whatever its type: an input sees a foreign type to refuse it."""
        return f"{self.domain_id}/{name}/*/*"

    def name_of(self, key: str) -> str | None:
        """The topic name a data key of this domain carries (None for a key that is not one)."""
        chunks = key.split("/")
        if len(chunks) < 4 or chunks[0] != str(self.domain_id) or "::dds_::" not in chunks[-2]:
            return None
        return "/".join(chunks[1:-2])

    def type_suffix(self, typename: str) -> str:
        """The last two chunks of `typename`'s keys."""
        return f"{dds_type_name(typename)}/{self.hash_of(typename)}"


def domain_from_env() -> int:
    """ROS_DOMAIN_ID as a ROS host sets it; 0 when unset."""
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"ROS_DOMAIN_ID {text!r}: not a number") from None


def mangle(name: str) -> str:
    """A name as one chunk of a token: `/` as `%`, the root namespace as `%`."""
    return name.replace("/", "%") if name.strip("/") else "%"


def demangle(chunk: str) -> str:
    """The inverse of `mangle`."""
    return chunk.replace("%", "/")


@dataclass(frozen=True)
class Qos:
    """The QoS a token states (rmw_zenoh's compact string: empty fields are ROS' defaults)."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def token(self) -> str:
        reliability = "" if self.reliable else "2"
        durability = "1" if self.transient_local else ""
        return f"{reliability}:{durability}:,{self.depth}:,:,:,,"


@dataclass(frozen=True)
class NodeName:
    """A node on the graph: its session, its id within it, its namespace and name."""

    zid: str
    node_id: int
    namespace: str
    name: str

    def token(self, graph: RosGraph) -> str:
        return f"{self._prefix(graph, self.node_id)}/NN/{ENCLAVE}/{mangle(self.namespace)}/{self.name}"

    def entity_token(
        self, graph: RosGraph, entity_id: int, kind: EntityKind, name: str, typename: str, qos: Qos
    ) -> str:
        """The token of one of the node's publishers, subscribers or services on topic `name`."""
        return (
            f"{self._prefix(graph, entity_id)}/{kind}/{ENCLAVE}/{mangle(self.namespace)}/{self.name}/"
            f"{mangle('/' + name)}/{dds_type_name(typename)}/{graph.hash_of(typename)}/{qos.token()}"
        )

    def _prefix(self, graph: RosGraph, entity_id: int) -> str:
        return f"{ADMIN_SPACE}/{graph.domain_id}/{self.zid}/{self.node_id}/{entity_id}"


class Attachments:
    """One publisher's attachments: its GID and the next sequence number (thread-safe)."""

    def __init__(self) -> None:
        self.gid = os.urandom(GID_SIZE)
        self._sequence = 0
        self._lock = threading.Lock()

    def next(self) -> bytes:
        """The attachment of the next sample, stamped now (wall clock, as rmw_zenoh's source timestamp)."""
        with self._lock:
            self._sequence += 1
            sequence = self._sequence
        return ATTACHMENT.pack(sequence, time.time_ns(), GID_SIZE, self.gid)

    def reply(self, request: bytes) -> bytes:
        """A service reply's attachment: the request's sequence number and GID, stamped now."""
        sequence, _, gid = parse_attachment(request)
        return ATTACHMENT.pack(sequence, time.time_ns(), GID_SIZE, gid)


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID) of an rmw_zenoh attachment, or AttachmentError."""
    if len(data) != ATTACHMENT.size:
        raise AttachmentError(f"an attachment of {len(data)} bytes, not rmw_zenoh's {ATTACHMENT.size}")
    sequence, stamp, length, gid = ATTACHMENT.unpack(data)
    if length != GID_SIZE:
        raise AttachmentError(f"an attachment whose GID length byte says {length}, not {GID_SIZE}")
    return sequence, stamp, gid
