"""Who publishes, subscribes and serves what: the bus's graph, as Zenoh liveliness tokens.

Zenoh alone cannot say that the server *subscribes* to `cmd_vel`, or what type a silent latched
key carries. So every publisher, subscription and service of a `Node` declares a liveliness
token (rmw_zenoh announces ROS 2 entities the same way) whose key spells out what it is:

    simbot_graph/<kind>/<type with '/' as '%'>/<key>

with kind `pub`, `sub` or `srv`. A token lives exactly as long as its entity, or until its
process dies, so `discover` lists the live graph, which `simbot topics` prints.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal

import zenoh

from simbot.bus.options import zenoh_reason

logger = logging.getLogger(__name__)

PREFIX = "simbot_graph"
Kind = Literal["pub", "sub", "srv"]
KINDS: tuple[Kind, ...] = ("pub", "sub", "srv")
SERVICE_TYPE = "json"
"""What a service carries: JSON requests and replies (world control)."""


@dataclass(frozen=True, order=True)
class Endpoint:
    """One live entity on the bus: its key, its kind and the ROS 2 type (or `json`) it carries."""

    key: str
    kind: Kind
    typename: str


def token_key(kind: Kind, typename: str, key: str) -> str:
    """The liveliness key that announces an entity."""
    return f"{PREFIX}/{kind}/{typename.replace('/', '%')}/{key}"


def parse_token(token: str) -> Endpoint | None:
    """The entity a liveliness key announces, or None for a key that is not one of ours."""
    parts = token.split("/", 3)
    if len(parts) != 4 or parts[0] != PREFIX or parts[1] not in KINDS:
        return None
    kind: Kind = parts[1]  # narrowed to a Kind by the check against KINDS above
    return Endpoint(parts[3], kind, parts[2].replace("%", "/"))


class Announcement:
    """A liveliness token that announces one entity until `close`."""

    def __init__(self, session: zenoh.Session, kind: Kind, typename: str, key: str) -> None:
        self._token: zenoh.LivelinessToken | None = session.liveliness().declare_token(token_key(kind, typename, key))

    def close(self) -> None:
        """Withdraw the announcement."""
        token, self._token = self._token, None
        if token is None:
            return
        try:
            token.undeclare()
        except zenoh.ZError as exc:  # the session is already closed
            logger.debug("undeclare token: %s", zenoh_reason(exc))


def discover(session: zenoh.Session, namespace: str = "", timeout: float = 1.0) -> list[Endpoint]:
    """Every live entity whose key is in `namespace`, sorted by key; each (key, kind, type) once."""
    scope = f"{namespace.strip('/')}/**" if namespace.strip("/") else "**"
    found: set[Endpoint] = set()
    for reply in session.liveliness().get(f"{PREFIX}/*/*/{scope}", timeout=timeout):
        if reply.ok is None:
            continue
        endpoint = parse_token(str(reply.ok.key_expr))
        if endpoint is not None:
            found.add(endpoint)
    return sorted(found)
