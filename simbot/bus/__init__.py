"""The bus layer: Zenoh sessions, ROS topic keys, the CDR codec and message constructors.

It knows nothing of physics or SDF (SPEC §7): the simulator and the clients both build on it.
"""

from __future__ import annotations

from simbot.bus.codec import DecodeError, EncodeError, UnknownMessageType, decode, encode, message_type
from simbot.bus.forks import ForkedSessionError
from simbot.bus.keys import topic_key
from simbot.bus.node import BusOpenError, Inbox, Node, Publisher, Subscription
from simbot.bus.options import BusConfigError, BusOptions, add_bus_arguments, zenoh_config
from simbot.bus.services import BadRequest, Queryable, Request, RosRequest, RosService, ServiceError

__all__ = [
    "BadRequest",
    "BusConfigError",
    "BusOpenError",
    "ForkedSessionError",
    "BusOptions",
    "DecodeError",
    "EncodeError",
    "Inbox",
    "Node",
    "Publisher",
    "Queryable",
    "Request",
    "RosRequest",
    "RosService",
    "ServiceError",
    "Subscription",
    "UnknownMessageType",
    "add_bus_arguments",
    "decode",
    "encode",
    "message_type",
    "topic_key",
    "zenoh_config",
]
