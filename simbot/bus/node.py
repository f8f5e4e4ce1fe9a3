"""One Zenoh session with a key namespace: publishers, subscriptions, inboxes and services.

Every key is rmw_zenoh's (`simbot.bus.rmw`): a topic `odom` in namespace `ns` is the key
`0/ns/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_…`, each sample carries rmw_zenoh's attachment,
and the session is a ROS 2 node on the graph (`graph.py`), so ROS 2 nodes on rmw_zenoh and
simbot's programs share one key space and every message goes out once. Within simbot a topic is
still named by `Node.key` (`ns/odom`), the name world state counts inputs by.

Congestion control: publishers DROP by default, so a slow subscriber never slows the
simulation (SPEC §4); `drop=False` gives BLOCK for data that must arrive, and latched publishers
BLOCK too: a latched message (a map, a description, a joint's state) is put once, and a
congested link at that moment (a first step's flood of images) must not lose it.

Latched topics ("transient local": `robot_description`, `tf_static`, `detachable_joint/state`)
use Zenoh's own mechanism, the `zenoh.ext` advanced publisher with a cache of one sample and
publisher detection, read by an advanced subscriber with history and late-publisher detection.
It is what rmw_zenoh uses for TRANSIENT_LOCAL, so a ROS 2 node on rmw_zenoh gets the latest
value on joining, and it also covers a subscriber that starts before the publisher. A plain Zenoh
user (`z_sub -k '0/ns/tf_static/**'`) receives every later put, and for the latest value the
latched publisher also answers a plain `get` on the key (`z_get -s '0/ns/tf_static/*/*'`) from
a queryable of its own. `Node.subscribe(..., latched=True)` does all this for our programs.

Zenoh runs callbacks on its own threads: the callbacks given here must only queue (append to a
deque, set a flag) and return. `Inbox` and `Queryable` are built that way for the simulation
loop, which drains them between steps.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, Literal, Protocol, TypeVar

import zenoh
import zenoh.ext

from simbot.bus.codec import DecodeError, checked_typename, decode, message_type
from simbot.bus.forks import check_fork_safe, zenoh_starts
from simbot.bus.graph import Announcement
from simbot.bus.keys import topic_key
from simbot.bus.options import BusOptions, Role, zenoh_config, zenoh_reason
from simbot.bus.publisher import Publisher, Route, Watching, direct
from simbot.bus.rmw import AttachmentError, EntityKind, NodeName, Qos, parse_attachment
from simbot.bus.services import (
    JSON_ENCODING,
    Answering,
    Queryable,
    RosService,
    ServiceError,
    parse_reply,
    undeclare,
)

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11

logger = logging.getLogger(__name__)

WARNING_PERIOD_S = 1.0
TIMEOUT_REPLY = "Timeout"  # the error payload Zenoh delivers to a get when its timeout expires

M = TypeVar("M")
WarningPolicy = Literal["rate-limited", "always", "none"]
"""How a refused input is logged: at most once a second per key, every time, or not at all."""


class BusOpenError(OSError):
    """The Zenoh session could not be opened (endpoint in use, no server to connect to)."""


class _Closable(Protocol):
    def close(self) -> None: ...


_T = TypeVar("_T", bound=_Closable)


class RateLimitedWarnings:
    """At most one warning per key per period; the ones held back are counted in the next."""

    def __init__(self, period_s: float = WARNING_PERIOD_S) -> None:
        self._period_s = period_s
        self._lock = threading.Lock()
        self._next: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def warn(self, key: str, message: str) -> None:
        """Log `message` about `key` now, or count it when one was logged less than a period ago."""
        now = time.monotonic()
        with self._lock:
            if now < self._next.get(key, 0.0):
                self._held[key] = self._held.get(key, 0) + 1
                return
            self._next[key] = now + self._period_s
            held = self._held.pop(key, 0)
        suffix = f" ({held} more since the last warning)" if held else ""
        logger.warning("%s: %s%s", key, message, suffix)


class Subscription(Generic[M]):
    """Decodes every sample on one key and hands the message to a callback; bad payloads are counted."""

    def __init__(
        self,
        session: zenoh.Session,
        route: Route,
        callback: Callable[[M], None],
        *,
        latched: bool,
        warnings: RateLimitedWarnings,
    ) -> None:
        message_type(route.typename)  # an unknown type name fails here, not in a Zenoh thread
        self.key = route.name
        self.typename = route.typename
        self.dropped = 0
        self.received = 0
        self._callback = callback
        self._warnings = warnings
        self._lock = threading.Lock()
        self._closed = False
        self._subscriber: Any
        if latched:
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                session,
                route.key,
                self._on_sample,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
            )
        else:
            self._subscriber = session.declare_subscriber(route.key, self._on_sample)
        self._announcement = Announcement(session, route.token) if route.token else None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh thread: decode, count, hand over; never raises into Zenoh."""
        if self._closed or sample.kind != zenoh.SampleKind.PUT:
            return  # samples Zenoh queued before close() are not delivered after it
        try:
            msg = decode(sample.payload.to_bytes(), self.typename)
        except DecodeError as exc:
            with self._lock:
                self.dropped += 1
            self._warnings.warn(self.key, f"dropped a payload that is not a valid {exc}")
            return
        with self._lock:
            self.received += 1
        try:
            self._callback(msg)
        except Exception:
            logger.exception("%s: subscription callback failed", self.key)

    def close(self) -> None:
        """Undeclare the subscriber; nothing reaches the callback afterwards."""
        self._closed = True
        if self._announcement is not None:
            self._announcement.close()
        undeclare(self._subscriber)


@dataclass(frozen=True)
class Refused:
    """A sample an inbox refused on arrival, and why: the loop counts it with the key's drops."""

    reason: str
    warning: WarningPolicy = "rate-limited"
    """A foreign type warns on its first sample whatever else was warned of, and never again: one
    warning per publisher's type, not one a second."""


class Inbox:
    """Raw payloads of one topic, queued by Zenoh and drained by the simulation loop.

    It listens to the topic's keys of every type: a sample of another type (a ROS node publishing
    `cmd_vel` as a TwistStamped: another DDS type and hash) is refused with one warning per type,
    and one with a malformed attachment is refused; a sample without an attachment (a plain Zenoh
    put) is taken. The deque is bounded: when it is full the oldest payload goes (the newest
    command is the one that matters) and `overflowed` counts it.
    """

    def __init__(self, session: zenoh.Session, route: Route, suffix: str, pattern: str, maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError(f"inbox {route.name!r}: maxlen must be ≥ 1, not {maxlen}")
        self.key = route.name
        self.overflowed = 0
        self.received = 0
        """Payloads that arrived, counted as they arrive (before anyone drains them)."""
        self.on_arrival: Callable[[], None] | None = None
        """Called (on Zenoh's thread) after each payload is queued: its loop learns that mail came
        without asking every inbox every step."""
        self._suffix = "/" + suffix
        self._foreign: set[str] = set()
        self._queue: deque[bytes | Refused] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self._subscriber = session.declare_subscriber(pattern, direct(self._on_sample))  # it only queues
        self._announcement = Announcement(session, route.token) if route.token else None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        item = self._refusal(sample) or sample.payload.to_bytes()
        with self._lock:
            self.received += 1
            if len(self._queue) == self._queue.maxlen:
                self.overflowed += 1
            self._queue.append(item)
        arrival = self.on_arrival  # read once: the loop may clear it meanwhile (the input closed)
        if arrival is not None:
            arrival()

    def _refusal(self, sample: zenoh.Sample) -> Refused | None:
        """Why a sample is refused before decoding: another type's key, or a malformed attachment."""
        key = str(sample.key_expr)
        if not key.endswith(self._suffix):
            kind = "/".join(key.split("/")[-2:])
            first = kind not in self._foreign
            self._foreign.add(kind)
            reason = f"a publisher of another type ({kind}) on this topic is ignored"
            return Refused(reason, "always" if first else "none")
        if sample.attachment is not None:
            try:
                parse_attachment(sample.attachment.to_bytes())
            except AttachmentError as exc:
                return Refused(str(exc))
        return None

    @property
    def pending(self) -> bool:
        """Whether something arrived since the last drain (a length read needs no lock)."""
        return bool(self._queue)

    def drain(self) -> list[bytes | Refused]:
        """What arrived since the last drain, oldest first: payloads, and the samples refused."""
        if not self._queue:  # most steps: nothing came (a length read needs no lock)
            return []
        with self._lock:
            items = list(self._queue)
            self._queue.clear()
        return items

    def close(self) -> None:
        """Undeclare the subscriber."""
        if self._announcement is not None:
            self._announcement.close()
        undeclare(self._subscriber)


class Node:
    """A Zenoh session (server or client role) plus the key namespace; a context manager."""

    def __init__(self, options: BusOptions, role: Role, name: str | None = None) -> None:
        """`name`: the node's name on the ROS 2 graph (default: the server `simbot`, a client after its program)."""
        self.options = options
        self.hosts_helpers = True
        """Whether a process it starts can join its bus (`helper_options`): a render worker then puts
        its camera's frames itself."""
        self.role = role
        self.namespace = options.namespace
        self.robot_namespace = options.robot_namespace.strip("/")
        self.graph = options.ros
        self._warnings = RateLimitedWarnings()
        self._entities: list[_Closable] = []
        self._entity_ids = 0
        self._publishers: list[Publisher] = []
        self.watching = Watching()
        """Changes of who subscribes to this node's publishers (`Watching`)."""
        self._by_name: dict[str, list[Publisher]] = {}
        config = zenoh_config(options, role)
        check_fork_safe()
        zenoh_starts()
        try:
            self.session = zenoh.open(config)
        except zenoh.ZError as exc:
            raise BusOpenError(f"cannot open the Zenoh {role} session: {zenoh_reason(exc)}") from None
        namespace = "/" + "/".join(part for part in (self.namespace.strip("/"), self.robot_namespace) if part)
        self.ros_node = NodeName(str(self.session.info.zid()), 0, namespace, name or _node_name(role))
        self._node_token = Announcement(self.session, self.ros_node.token(self.graph))
        self._robot_nodes: dict[str, tuple[NodeName, Announcement]] = {}
        self._unheard: list[Publisher] | None = None
        """Publishers that listen for subscribers at the end of `listening_later`."""

    def key(self, topic: str) -> str:
        """The Zenoh key of `topic` in this node's namespace. With a robot namespace, as ROS resolves
        names in a node's namespace: a relative topic (`cmd_vel`) under it, an absolute one
        (`/clock`) in the bus's namespace alone."""
        if topic.startswith("/") or not self.robot_namespace:
            return topic_key(topic, self.namespace)
        return topic_key(topic, "/".join(part for part in (self.namespace, self.robot_namespace) if part))

    def data_key(self, topic: str, typename: str) -> str:
        """The Zenoh key of `topic`'s samples of `typename`, for a plain Zenoh subscriber or put."""
        return self.graph.data_key(self.key(topic), typename)

    def route(
        self, name: str, typename: str, kind: EntityKind | None, qos: Qos | None = None, node: NodeName | None = None
    ) -> Route:
        """The route of an entity on topic or service `name` (as `key` gives it), announced as `kind`
        (None: not) by `node` (default: this session's own node on the graph)."""
        token = None
        if kind is not None:
            self._entity_ids += 1
            owner = node or self.ros_node
            token = owner.entity_token(self.graph, self._entity_ids, kind, name, typename, qos or Qos())
        return Route(name, self.graph.data_key(name, typename), typename, token)

    def robot_node(self, namespace: str) -> NodeName:
        """A node of its own on the graph for the robot in `namespace` (`/tug_7/simbot`), announced
        from the first call until `release_robot_node`: a fleet's entities grouped by robot, as each
        robot would run its own node. (Zenoh declares a token in time that grows with its siblings:
        measured, 1.7 ms for the 14 000th entity of one node, 0.04 ms with 28 a node.)"""
        if namespace not in self._robot_nodes:
            self._entity_ids += 1
            scope = "/".join(part for part in (self.ros_node.namespace.strip("/"), namespace.strip("/")) if part)
            node = NodeName(self.ros_node.zid, self._entity_ids, "/" + scope, self.ros_node.name)
            self._robot_nodes[namespace] = (node, Announcement(self.session, node.token(self.graph)))
        return self._robot_nodes[namespace][0]

    def release_robot_node(self, namespace: str) -> None:
        """The robot in `namespace` left: its node leaves the graph."""
        if (held := self._robot_nodes.pop(namespace, None)) is not None:
            held[1].close()

    def _keep(self, entity: _T) -> _T:
        self._entities.append(entity)
        return entity

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
    ) -> Publisher:
        """A publisher on `topic` of `msgtype` (a `messages` class or a ROS 2 type name); `latched`
        serves the latest message to late joiners (TRANSIENT_LOCAL), `drop=False` blocks (RELIABLE);
        `frame_prefix` puts the frames of what it sends under a robot's namespace; `announced=False`:
        the key's owner announces it (a server's render worker puts what the server announces);
        `watched_only`: a put no subscriber matches is neither encoded nor sent (the server's);
        `ros_node`: the node on the graph that announces it (default: this session's)."""
        typename = checked_typename(msgtype)
        qos = Qos(reliable=not drop or latched, transient_local=latched, depth=1 if latched else 10)
        route = self.route(self.key(topic), typename, "MP" if announced else None, qos, ros_node)
        publisher = Publisher(
            self.session,
            route,
            latched=latched,
            drop=drop,
            frame_prefix=frame_prefix,
            watched_only=watched_only,
            listening=self._unheard is None,
            watching=self.watching,
        )
        if self._unheard is not None:
            self._unheard.append(publisher)
        self._publishers.append(publisher)
        self._by_name.setdefault(route.name, []).append(publisher)
        return self._keep(publisher)

    @contextlib.contextmanager
    def listening_later(self) -> Iterator[None]:
        """The publishers declared within follow who subscribes from its end (`Publisher.listen`):
        a server builds its world's thousand tugs, then listens."""
        self._unheard = []
        try:
            yield
        finally:
            unheard, self._unheard = self._unheard, None
            for publisher in unheard:
                publisher.listen()

    def refresh_subscribers(self) -> None:
        """Every publisher that knows of no subscriber asks Zenoh again (`Publisher.refresh`): world
        control calls it before the steps a request asks for, so that they see, in the order the
        bus delivered them, the subscribers declared before the request."""
        self._publishers = [publisher for publisher in self._publishers if publisher.refresh()]

    def _heard(self, name: str) -> None:
        """This node subscribed to topic `name`: its own publishers of it know at once."""
        for publisher in self._by_name.get(name, []):
            publisher.refresh()

    def subscribe(
        self, topic: str, typename: str, callback: Callable[[Any], None], *, latched: bool = False
    ) -> Subscription[Any]:
        """Decoded messages of `topic` to `callback`, on a Zenoh thread: the callback should only queue."""
        message_type(typename)
        route = self.route(self.key(topic), typename, "MS", Qos(transient_local=latched, depth=1 if latched else 10))
        subscription: Subscription[Any] = Subscription(
            self.session, route, callback, latched=latched, warnings=self._warnings
        )
        self._heard(route.name)
        return self._keep(subscription)

    def inbox(self, topic: str, typename: str, maxlen: int = 64, ros_node: NodeName | None = None) -> Inbox:
        """Raw payloads of `topic` (announced as `typename` by `ros_node`, default this session's
        node), for a loop that decodes and counts them itself."""
        message_type(typename)
        name = self.key(topic)
        route = self.route(name, typename, "MS", node=ros_node)
        inbox = Inbox(self.session, route, self.graph.type_suffix(typename), self.graph.any_type_key(name), maxlen)
        self._heard(name)
        return self._keep(inbox)

    def queryable(self, key_suffix: str, capacity: int = 64) -> Queryable:
        """A JSON service at `key_suffix` (in the namespace), polled by the simulation loop."""
        return self._keep(Queryable(self.session, self.key("/" + key_suffix.lstrip("/")), capacity))

    def ros_service(self, name: str, typename: str, capacity: int = 64, ros_node: NodeName | None = None) -> RosService:
        """A ROS 2 service `name` (in the namespace) of service type `typename` (`std_srvs/srv/Empty`),
        on rmw_zenoh's key and the graph (announced by `ros_node`, default this session's node),
        polled by the simulation loop."""
        route = self.route(self.key("/" + name.lstrip("/")), typename, "SS", node=ros_node)
        assert route.token is not None  # announced: kind SS
        return self._keep(RosService(self.session, route.name, route.key, typename, route.token, capacity))

    def answering(self, key_suffix: str) -> None:
        """A queryable at `key_suffix` (in the namespace) that answers `{}` at once, on Zenoh's thread:
        a process that publishes on this bus asks it to know that what it put before has been routed
        by this session (its samples and its query share one link, in order)."""
        self._keep(Answering(self.session, self.key("/" + key_suffix.lstrip("/"))))

    def call(self, key_suffix: str, payload: Mapping[str, Any] | bytes, timeout: float = 5.0) -> dict[str, Any]:
        """Ask the JSON service at `key_suffix` (a world's, in the bus's namespace); a dict is sent as JSON,
        bytes as they are."""
        key = self.key("/" + key_suffix.lstrip("/"))
        body = bytes(payload) if isinstance(payload, (bytes, bytearray)) else json.dumps(dict(payload)).encode()
        asked = time.monotonic()
        replies = self.session.get(
            key,
            payload=body,
            encoding=JSON_ENCODING,
            timeout=timeout,
            consolidation=zenoh.ConsolidationMode.NONE,
        )
        for reply in replies:
            if reply.ok is not None:
                return parse_reply(key, reply.ok.payload.to_bytes())
            error = reply.err.payload.to_string() if reply.err is not None else ""
            if error != TIMEOUT_REPLY:
                raise ServiceError(f"{key}: {error}")
        if time.monotonic() - asked < timeout / 2:  # the query ended early: no queryable took it
            raise TimeoutError(
                f"{key}: nothing answers (is the server running, with the same namespace, and may this session ask it?)"
            )
        raise TimeoutError(f"{key}: no reply within {timeout:g} s (is the server running, with the same namespace?)")

    def close(self) -> None:
        """Undeclare everything and close the session; safe to call twice."""
        entities, self._entities = self._entities, []
        for entity in reversed(entities):
            entity.close()
        if not self.session.is_closed():
            self.session.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def _node_name(role: Role) -> str:
    """The server is `simbot`; a client is named after its program and process (`simbot_merger_4242`)."""
    if role == "server":
        return "simbot"
    program = os.path.basename(sys.argv[0] or "python").removesuffix(".py").replace("-", "_")
    stem = "".join(c if c.isalnum() or c == "_" else "_" for c in program) or "client"
    return f"{stem}_{os.getpid()}"
