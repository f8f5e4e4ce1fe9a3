"""The node's API within one process: no Zenoh, no CDR, nothing on any network.

A learning environment that no one watches steps its world in its own process (simbot.gym.local);
the server's systems still publish and take commands through a node, and this one hands each
message object to the subscribers and inboxes of its key in the same call, as a Zenoh session
delivers a put to its own subscribers, only without encoding it. What a subscriber gets is the
message the system put (frame ids prefixed as `Publisher` prefixes them), so an observation made
from it equals one made from the same message after a CDR round trip (tests/test_gym_vector.py).

A latched publisher hands its latest message to a subscriber that comes later. Services and
queryables (world control, the ROS services of a few systems) are declared and never called: the
process that owns the world calls it directly.

Each class is the bus class it stands in for, with every method a system or an observer calls
overridden and no Zenoh session behind it, so that code typed for the bus takes it unchanged.
"""

from __future__ import annotations

import contextlib
import logging
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from simbot.bus.codec import checked_typename, decode, message_type
from simbot.bus.frames import with_frame_prefix
from simbot.bus.keys import topic_key
from simbot.bus.node import Inbox, Node, Publisher, Subscription
from simbot.bus.options import BusOptions
from simbot.bus.publisher import Watching
from simbot.bus.rmw import NodeName
from simbot.bus.services import Queryable, Request, RosRequest, RosService

log = logging.getLogger(__name__)


class LocalHub:
    """Who listens on which key; the one owner of a local node's routes."""

    def __init__(self) -> None:
        self.listeners: dict[str, list[Callable[[Any], None]]] = {}
        self.latest: dict[str, Any] = {}
        self.watching = Watching()

    def listen(self, key: str, deliver: Callable[[Any], None]) -> None:
        self.listeners.setdefault(key, []).append(deliver)
        self.watching.changed()
        if key in self.latest:
            deliver(self.latest[key])

    def forget(self, key: str, deliver: Callable[[Any], None]) -> None:
        listeners = self.listeners.get(key, [])
        if deliver in listeners:
            listeners.remove(deliver)
            self.watching.changed()

    def put(self, key: str, msg: Any, latched: bool) -> None:
        if latched:
            self.latest[key] = msg
        for deliver in list(self.listeners.get(key, ())):
            try:
                deliver(msg)
            except Exception:
                log.exception("%s: subscription callback failed", key)


class LocalPublisher(Publisher):
    """`Publisher`'s API: `put` hands the message to every listener of its key at once."""

    def __init__(self, hub: LocalHub, key: str, typename: str, latched: bool, frame_prefix: str) -> None:
        self.key = key
        self.typename = typename
        self.latched = latched
        self.frame_prefix = frame_prefix
        self._hub = hub

    def put(self, msg: Any) -> None:
        self._hub.put(self.key, with_frame_prefix(msg, self.frame_prefix) if self.frame_prefix else msg, self.latched)

    def put_raw(self, data: bytes | bytearray) -> None:
        self.put(decode(bytes(data), self.typename))

    @property
    def has_subscribers(self) -> bool:
        return self.latched or bool(self._hub.listeners.get(self.key))

    def await_subscribers(self, timeout: float) -> bool:
        return self.has_subscribers

    def close(self) -> None:
        self._hub.latest.pop(self.key, None)


class LocalSubscription(Subscription[Any]):
    """`Subscription`'s API: the callback runs in the publisher's call."""

    def __init__(self, hub: LocalHub, key: str, callback: Callable[[Any], None]) -> None:
        self.key = key
        self.received = 0
        self.dropped = 0
        self._hub = hub
        self._callback = callback
        hub.listen(key, self._deliver)

    def _deliver(self, msg: Any) -> None:
        self.received += 1
        self._callback(msg)

    def close(self) -> None:
        self._hub.forget(self.key, self._deliver)


class LocalInbox(Inbox):
    """`Inbox`'s API, holding message objects (an `Input` takes them as they are, undecoded)."""

    def __init__(self, hub: LocalHub, key: str, maxlen: int) -> None:
        self.key = key
        self.received = 0
        self.overflowed = 0
        self._queue: deque[Any] = deque(maxlen=maxlen)
        self.on_arrival: Callable[[], None] | None = None
        self._hub = hub
        hub.listen(key, self._append)

    def _append(self, msg: Any) -> None:
        self.received += 1
        if len(self._queue) == self._queue.maxlen:
            self.overflowed += 1
        self._queue.append(msg)
        arrival = self.on_arrival  # read once: the loop may clear it meanwhile (the input closed)
        if arrival is not None:
            arrival()

    def drain(self) -> list[Any]:
        items = list(self._queue)
        self._queue.clear()
        return items

    def close(self) -> None:
        self._hub.forget(self.key, self._append)


class LocalQueryable(Queryable):
    """A declared JSON service that no one can reach: it never has a request."""

    def __init__(self, key: str) -> None:
        self.key = key

    def poll(self) -> list[Request]:
        return []

    def close(self) -> None:
        pass


class LocalRosService(RosService):
    """A declared ROS service that no one can reach: it never has a request."""

    def __init__(self, name: str, typename: str) -> None:
        self.name = name
        self.typename = typename

    def poll(self) -> list[RosRequest]:
        return []

    def close(self) -> None:
        pass


class LocalNode(Node):
    """The part of `Node`'s API that systems and an environment's observer use, in one process."""

    namespace = ""
    robot_namespace = ""

    def __init__(self) -> None:
        self.hub = LocalHub()
        self.watching = self.hub.watching
        self.options = BusOptions()
        self.hosts_helpers = False
        """No other process can reach it: a render worker hands its frames back to the world, which
        puts them here."""

    def key(self, topic: str) -> str:
        return topic_key(topic)

    def publisher(
        self,
        topic: str,
        msgtype: type[Any] | str,
        *,
        latched: bool = False,
        drop: bool = True,
        frame_prefix: str = "",
        announced: bool = True,
        watched_only: bool = False,
        ros_node: NodeName | None = None,
    ) -> LocalPublisher:
        return LocalPublisher(self.hub, self.key(topic), checked_typename(msgtype), latched, frame_prefix)

    def refresh_subscribers(self) -> None:
        """A local listener is known the moment it listens."""

    @contextlib.contextmanager
    def listening_later(self) -> Iterator[None]:
        """Nothing to put off: a local listener is known the moment it listens."""
        yield

    def subscribe(
        self, topic: str, typename: str, callback: Callable[[Any], None], *, latched: bool = False
    ) -> LocalSubscription:
        message_type(typename)
        return LocalSubscription(self.hub, self.key(topic), callback)

    def inbox(self, topic: str, typename: str, maxlen: int = 64, ros_node: NodeName | None = None) -> LocalInbox:
        message_type(typename)
        return LocalInbox(self.hub, self.key(topic), maxlen)

    def queryable(self, key_suffix: str, capacity: int = 64) -> LocalQueryable:
        return LocalQueryable(self.key("/" + key_suffix.lstrip("/")))

    def ros_service(
        self, name: str, typename: str, capacity: int = 64, ros_node: NodeName | None = None
    ) -> LocalRosService:
        return LocalRosService(self.key(name), typename)

    def robot_node(self, namespace: str) -> NodeName:
        """A name alone: nothing in one process is on a graph."""
        return NodeName("local", 0, "/" + namespace, "simbot")

    def release_robot_node(self, namespace: str) -> None:
        """Nothing was announced."""

    def answering(self, key_suffix: str) -> None:
        """A lockstep barrier's key: no helper process can call it."""

    def close(self) -> None:
        self.hub.listeners.clear()
        self.hub.latest.clear()
