"""Who publishes, subscribes and serves what: the bus's graph, as Zenoh liveliness tokens.

Zenoh alone cannot say that the server *subscribes* to `cmd_vel`, or what type a silent latched
key carries. So every publisher, subscription and service of a `Node` declares a liveliness
token whose key spells out what it is, and lives exactly as long as its entity (or its process):

- topics and ROS services: rmw_zenoh's own tokens (`@ros2_lv/...`, `simbot.bus.rmw`), so that a
  ROS 2 node on rmw_zenoh sees them in `ros2 topic list` and `ros2 service list`;
- simbot's JSON services (world control), which no ROS tool can call: `simbot_graph/srv/json/<name>`.

`discover` reads both back, which `simbot topics` prints.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import zenoh

from simbot.bus.options import zenoh_reason
from simbot.bus.rmw import ADMIN_SPACE, RosGraph, demangle
from simbot.bus.type_hashes import ros_typename

logger = logging.getLogger(__name__)

LIVELINESS_REPLIES = 1 << 16
"""Room for a liveliness query's replies: more than any graph holds (a fleet of nine tugs has about
700 tokens). Zenoh's default channel holds 256; a receive thread finding it full waits, holding
the session's lock, and a query begun meanwhile waits for that lock: CI's test_fleet_spawn hung
there (the receive thread parked in the channel, the next `get` in the session's lock)."""
FINALISE_GRACE_S = 2.0
"""Seconds past a liveliness query's timeout after which its replies so far are taken as all."""
FIRST_POLL_S, LAST_POLL_S = 0.0002, 0.005
"""The pauses between looks at a query's replies: short while they come, growing while none does."""
JSON_PREFIX = "simbot_graph/srv/json"
Kind = Literal["pub", "sub", "srv"]
KINDS: tuple[Kind, ...] = ("pub", "sub", "srv")
ROS_KINDS: dict[str, Kind] = {"MP": "pub", "MS": "sub", "SS": "srv"}
SERVICE_TYPE = "json"
"""What a JSON service carries: JSON requests and replies (world control)."""
TOPIC_CHUNK = 9
"""Where an entity token holds the topic's name: after the prefix, domain, session, node, entity,
kind, enclave, namespace and node name."""


@dataclass(frozen=True, order=True)
class Endpoint:
    """One live entity on the bus: its topic or service name (no leading slash), its kind and the
    ROS 2 type (or `json`) it carries."""

    key: str
    kind: Kind
    typename: str


def json_token(name: str) -> str:
    """The liveliness key that announces a JSON service."""
    return f"{JSON_PREFIX}/{name}"


def parse_token(token: str) -> Endpoint | None:
    """The entity a liveliness key announces, or None for a key that is none of ours or rmw_zenoh's."""
    if token.startswith(JSON_PREFIX + "/"):
        return Endpoint(token.removeprefix(JSON_PREFIX + "/"), "srv", SERVICE_TYPE)
    parts = token.split("/")
    if len(parts) < TOPIC_CHUNK + 4 or parts[0] != ADMIN_SPACE or parts[5] not in ROS_KINDS:
        return None
    typename = ros_typename(parts[TOPIC_CHUNK + 1])
    if typename is None:
        return None
    return Endpoint(demangle(parts[TOPIC_CHUNK]).strip("/"), ROS_KINDS[parts[5]], typename)


class Announcement:
    """A liveliness token that announces one entity until `close`."""

    def __init__(self, session: zenoh.Session, token: str) -> None:
        self._token: zenoh.LivelinessToken | None = session.liveliness().declare_token(token)

    def close(self) -> None:
        """Withdraw the announcement."""
        token, self._token = self._token, None
        if token is None:
            return
        try:
            token.undeclare()
        except zenoh.ZError as exc:  # the session is already closed
            logger.debug("undeclare token: %s", zenoh_reason(exc))


def discover(
    session: zenoh.Session, namespace: str = "", timeout: float = 1.0, graph: RosGraph | None = None
) -> list[Endpoint]:
    """Every live entity whose name is in `namespace` (in `graph`'s domain), sorted; each (name, kind, type) once."""
    graph = graph or RosGraph()
    scope = namespace.strip("/")
    found: set[Endpoint] = set()
    for pattern in (f"{ADMIN_SPACE}/{graph.domain_id}/**", f"{JSON_PREFIX}/**"):
        replies = session.liveliness().get(pattern, zenoh.handlers.FifoChannel(LIVELINESS_REPLIES), timeout=timeout)
        for reply in _replies(replies, timeout):
            if reply.ok is None:
                continue
            endpoint = parse_token(str(reply.ok.key_expr))
            if endpoint is not None and (not scope or endpoint.key.startswith(scope + "/")):
                found.add(endpoint)
    return sorted(found)


def _replies(handler: zenoh.handlers.Handler[zenoh.Reply], timeout: float) -> Iterator[zenoh.Reply]:
    """A liveliness query's replies until Zenoh closes its channel (the query is finalised, at the
    latest at its timeout), read without blocking, so that a query Zenoh does not finalise cannot
    hold its caller: past its timeout and FINALISE_GRACE_S the replies so far are taken as all, with
    a warning."""
    deadline = time.monotonic() + timeout + FINALISE_GRACE_S
    pause = FIRST_POLL_S
    while time.monotonic() < deadline:
        try:
            reply = handler.try_recv()
        except zenoh.ZError:  # empty and closed: every reply is in
            return
        if reply is None:
            time.sleep(pause)
            pause = min(2 * pause, LAST_POLL_S)
            continue
        pause = FIRST_POLL_S
        yield reply
    logger.warning(
        "a liveliness query was not finalised %g s after its timeout; taking the replies so far", FINALISE_GRACE_S
    )
