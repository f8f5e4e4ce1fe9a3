"""One Zenoh session with a key namespace: publishers, subscriptions, inboxes and JSON services.

Congestion control: publishers DROP by default, so a slow subscriber never slows the
simulation (SPEC §4); `drop=False` gives BLOCK for data that must arrive.

Latched topics ("transient local": `robot_description`, `tf_static`, `detachable_joint/state`)
use Zenoh's own mechanism, the `zenoh.ext` advanced publisher with a cache of one sample and
publisher detection, read by an advanced subscriber with history and late-publisher detection.
It is what zenoh-bridge-ros2dds (since PR #524) and rmw_zenoh use for TRANSIENT_LOCAL, so a ROS 2
host behind the bridge gets the latest value on joining, and it also covers a subscriber that
starts before the publisher. A plain Zenoh user (`z_sub`) receives every later put, and for the
latest value the latched publisher also answers a plain `get` on the key (`z_get -s KEY`) from
a queryable of its own. `Node.subscribe(..., latched=True)` does all this for our programs.

Zenoh runs callbacks on its own threads: the callbacks given here must only queue (append to a
deque, set a flag) and return. `Inbox` and `Queryable` are built that way for the simulation
loop, which drains them between steps.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

import zenoh
import zenoh.ext

from simbot.bus.codec import DecodeError, decode, encode, message_type
from simbot.bus.frames import with_frame_prefix
from simbot.bus.graph import SERVICE_TYPE, Announcement
from simbot.bus.keys import topic_key
from simbot.bus.options import BusOptions, Role, zenoh_config, zenoh_reason

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11

logger = logging.getLogger(__name__)

WARNING_PERIOD_S = 1.0
CDR_ENCODING = zenoh.Encoding.APPLICATION_CDR
JSON_ENCODING = zenoh.Encoding.APPLICATION_JSON
TIMEOUT_REPLY = "Timeout"  # the error payload Zenoh delivers to a get when its timeout expires

M = TypeVar("M")


class BusOpenError(OSError):
    """The Zenoh session could not be opened (endpoint in use, no server to connect to)."""


class BadRequest(ValueError):
    """A service request whose payload is not a JSON object; str() is one line."""


class ServiceError(RuntimeError):
    """A service answered a call with an error, or with something other than a JSON object."""


class _Undeclarable(Protocol):
    def undeclare(self) -> None: ...


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


class Publisher:
    """Encodes messages and puts them on one key; latched publishers also serve the latest to late joiners.

    The publisher announces itself on the graph (`simbot.bus.graph`) at once when it is given the
    type it carries, else at its first `put`: a camera nobody watches is on the graph all the same.
    """

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        *,
        latched: bool,
        drop: bool,
        typename: str | None = None,
        frame_prefix: str = "",
        announced: bool = True,
    ) -> None:
        """`announced=False`: the key's owner announces it on the graph (a server's render worker
        puts what the server's own publisher announces)."""
        self.key = key
        self.frame_prefix = frame_prefix
        """Every frame id the messages carry goes out under it (`frames.with_frame_prefix`)."""
        self.latched = latched
        self.typename = typename
        self._session = session
        self._announced = announced
        self._announcement = Announcement(session, "pub", typename, key) if typename and announced else None
        congestion = zenoh.CongestionControl.DROP if drop else zenoh.CongestionControl.BLOCK
        self._encodings: dict[str, zenoh.Encoding] = {}
        self._latest: tuple[bytes, zenoh.Encoding] | None = None
        self._lock = threading.Lock()
        self._queryable: zenoh.Queryable[None] | None = None
        self._publisher: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        if latched:
            self._publisher = zenoh.ext.declare_advanced_publisher(
                session,
                key,
                encoding=CDR_ENCODING,
                congestion_control=congestion,
                cache=zenoh.ext.CacheConfig(1),
                publisher_detection=True,
            )
            self._queryable = session.declare_queryable(key, self._serve_latest, complete=True)
        else:
            self._publisher = session.declare_publisher(key, encoding=CDR_ENCODING, congestion_control=congestion)

    def _encoding(self, typename: str) -> zenoh.Encoding:
        """`application/cdr;TYPE`: lets a monitor decode a key without being told its type."""
        encoding = self._encodings.get(typename)
        if encoding is None:
            encoding = self._encodings[typename] = CDR_ENCODING.with_schema(typename)
        return encoding

    def put(self, msg: Any) -> None:
        """Encode `msg` as CDR and put it."""
        data = encode(with_frame_prefix(msg, self.frame_prefix) if self.frame_prefix else msg)
        if self._announcement is None and self._announced:
            self._announcement = Announcement(self._session, "pub", msg.__msgtype__, self.key)
        self._put(data, self._encoding(msg.__msgtype__))

    def put_raw(self, data: bytes | bytearray) -> None:
        """Put bytes as they are, as CDR of the publisher's type if it was given one: a recording played
        back goes out unchanged, a render worker's image encoded in place, and tests send garbage
        this way. (A latched publisher keeps a copy of its own.)"""
        kept = bytes(data) if self.latched else data
        self._put(kept, self._encoding(self.typename) if self.typename else CDR_ENCODING)

    def _put(self, data: bytes | bytearray, encoding: zenoh.Encoding) -> None:
        if self.latched:
            with self._lock:
                self._latest = (bytes(data), encoding)
        self._publisher.put(data, encoding=encoding)

    def _serve_latest(self, query: zenoh.Query) -> None:
        """Plain `get` on a latched key: reply with the latest payload (called on a Zenoh thread)."""
        with query:
            with self._lock:
                latest = self._latest
            if latest is not None:
                query.reply(self.key, latest[0], encoding=latest[1])

    @property
    def has_subscribers(self) -> bool:
        """Whether a subscriber matching the key is known (plain publishers only; latched ones say True)."""
        if not isinstance(self._publisher, zenoh.Publisher):
            return True
        # zenoh 1.10 returns a MatchingStatus (always truthy), though its stub says bool
        status: object = self._publisher.matching_status
        return bool(getattr(status, "matching", status))

    def close(self) -> None:
        """Undeclare the publisher (and the latched queryable)."""
        if self._announcement is not None:
            self._announcement.close()
        _undeclare(self._queryable)
        _undeclare(self._publisher)
        self._queryable = None


class Subscription(Generic[M]):
    """Decodes every sample on one key and hands the message to a callback; bad payloads are counted."""

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        typename: str,
        callback: Callable[[M], None],
        *,
        latched: bool,
        warnings: RateLimitedWarnings,
    ) -> None:
        message_type(typename)  # an unknown type name fails here, not in a Zenoh thread
        self.key = key
        self.typename = typename
        self.dropped = 0
        self.received = 0
        self._callback = callback
        self._warnings = warnings
        self._lock = threading.Lock()
        self._closed = False
        self._subscriber: _Undeclarable
        if latched:
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                session,
                key,
                self._on_sample,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
            )
        else:
            self._subscriber = session.declare_subscriber(key, self._on_sample)
        self._announcement = Announcement(session, "sub", typename, key)

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
        self._announcement.close()
        _undeclare(self._subscriber)


class Inbox:
    """Raw payloads of one key, queued by Zenoh and drained by the simulation loop.

    The deque is bounded: when it is full the oldest payload goes (the newest command is the one
    that matters) and `overflowed` counts it.
    """

    def __init__(self, session: zenoh.Session, key: str, typename: str, maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError(f"inbox {key!r}: maxlen must be ≥ 1, not {maxlen}")
        self.key = key
        self.overflowed = 0
        self.received = 0
        """Payloads that arrived, counted as they arrive (before anyone drains them)."""
        self._queue: deque[bytes] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self._subscriber = session.declare_subscriber(key, self._on_sample)
        self._announcement = Announcement(session, "sub", typename, key)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        data = sample.payload.to_bytes()
        with self._lock:
            self.received += 1
            if len(self._queue) == self._queue.maxlen:
                self.overflowed += 1
            self._queue.append(data)

    def drain(self) -> list[bytes]:
        """The payloads received since the last drain, oldest first."""
        with self._lock:
            items = list(self._queue)
            self._queue.clear()
        return items

    def close(self) -> None:
        """Undeclare the subscriber."""
        self._announcement.close()
        _undeclare(self._subscriber)


class Request:
    """One service request: its JSON payload, and a reply that may come later from any thread."""

    def __init__(self, query: zenoh.Query, key: str) -> None:
        self.key = key
        self._query = query
        payload = query.payload
        self.payload = payload.to_bytes() if payload is not None else b""
        self._replied = False
        self._lock = threading.Lock()

    def json(self) -> dict[str, Any]:
        """The payload as a JSON object; no payload is `{}`. BadRequest when malformed."""
        if not self.payload.strip():
            return {}
        try:
            value = json.loads(self.payload)
        except (UnicodeDecodeError, ValueError) as exc:
            raise BadRequest(f"{self.key}: malformed JSON: {' '.join(str(exc).split())}") from None
        except RecursionError:
            raise BadRequest(f"{self.key}: JSON nested too deeply") from None
        if not isinstance(value, dict):
            raise BadRequest(f"{self.key}: expected a JSON object, got {type(value).__name__}")
        return value

    def reply(self, obj: Mapping[str, Any]) -> None:
        """Answer with `obj` as JSON and finish the request."""
        text = json.dumps(dict(obj), allow_nan=False)
        self._finish(lambda: self._query.reply(self.key, text, encoding=JSON_ENCODING))

    def reply_error(self, message: str) -> None:
        """Answer with a Zenoh error reply (`Node.call` raises ServiceError with `message`)."""
        self._finish(lambda: self._query.reply_err(message))

    def _finish(self, send: Callable[[], None]) -> None:
        with self._lock:
            if self._replied:
                raise RuntimeError(f"{self.key}: request already answered")
            self._replied = True
            try:
                send()
            finally:
                self._query.drop()  # finalizes the query: the caller's get returns now, not at its timeout


class Queryable:
    """A JSON service on one key; requests wait in a FIFO channel until `poll` takes them."""

    def __init__(self, session: zenoh.Session, key: str, capacity: int) -> None:
        self.key = key
        self._queryable = session.declare_queryable(key, zenoh.handlers.FifoChannel(capacity), complete=True)
        self._announcement = Announcement(session, "srv", SERVICE_TYPE, key)

    def poll(self) -> list[Request]:
        """The requests that arrived since the last poll, without blocking."""
        requests = []
        while (query := self._queryable.try_recv()) is not None:
            requests.append(Request(query, self.key))
        return requests

    def close(self) -> None:
        """Undeclare the queryable."""
        self._announcement.close()
        _undeclare(self._queryable)


class Answering:
    """A queryable that answers `{}` at once on Zenoh's thread (`Node.answering`); off the graph."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self._queryable = session.declare_queryable(key, _answer_empty)

    def close(self) -> None:
        _undeclare(self._queryable)


def _undeclare(entity: _Undeclarable | None) -> None:
    if entity is None:
        return
    try:
        entity.undeclare()
    except zenoh.ZError as exc:  # already undeclared, or the session is closed
        logger.debug("undeclare: %s", zenoh_reason(exc))


class Node:
    """A Zenoh session (server or client role) plus the key namespace; a context manager."""

    def __init__(self, options: BusOptions, role: Role) -> None:
        self.options = options
        self.role = role
        self.namespace = options.namespace
        self.robot_namespace = options.robot_namespace.strip("/")
        self._warnings = RateLimitedWarnings()
        self._entities: list[_Closable] = []
        config = zenoh_config(options, role)
        try:
            self.session = zenoh.open(config)
        except zenoh.ZError as exc:
            raise BusOpenError(f"cannot open the Zenoh {role} session: {zenoh_reason(exc)}") from None

    def key(self, topic: str) -> str:
        """The Zenoh key of `topic` in this node's namespace. With a robot namespace, as ROS resolves
        names in a node's namespace: a relative topic (`cmd_vel`) under it, an absolute one
        (`/clock`) in the bus's namespace alone."""
        if topic.startswith("/") or not self.robot_namespace:
            return topic_key(topic, self.namespace)
        return topic_key(topic, "/".join(part for part in (self.namespace, self.robot_namespace) if part))

    def _keep(self, entity: _T) -> _T:
        self._entities.append(entity)
        return entity

    def publisher(
        self,
        topic: str,
        msgtype: type[Any] | str | None = None,
        *,
        latched: bool = False,
        drop: bool = True,
        frame_prefix: str = "",
    ) -> Publisher:
        """A publisher on `topic` of `msgtype` (a `messages` class or a ROS 2 type name, for the graph);
        `latched` serves the latest message to late joiners, `drop=False` blocks; `frame_prefix`
        puts the frames of what it sends under a robot's namespace."""
        typename = msgtype if isinstance(msgtype, str) or msgtype is None else msgtype.__msgtype__
        publisher = Publisher(
            self.session, self.key(topic), latched=latched, drop=drop, typename=typename, frame_prefix=frame_prefix
        )
        return self._keep(publisher)

    def subscribe(
        self, topic: str, typename: str, callback: Callable[[Any], None], *, latched: bool = False
    ) -> Subscription[Any]:
        """Decoded messages of `topic` to `callback`, on a Zenoh thread: the callback should only queue."""
        subscription: Subscription[Any] = Subscription(
            self.session, self.key(topic), typename, callback, latched=latched, warnings=self._warnings
        )
        return self._keep(subscription)

    def inbox(self, topic: str, typename: str, maxlen: int = 64) -> Inbox:
        """Raw payloads of `topic` (announced as `typename`), for a loop that decodes and counts them itself."""
        return self._keep(Inbox(self.session, self.key(topic), typename, maxlen))

    def queryable(self, key_suffix: str, capacity: int = 64) -> Queryable:
        """A JSON service at `key_suffix` (in the namespace), polled by the simulation loop."""
        return self._keep(Queryable(self.session, self.key("/" + key_suffix.lstrip("/")), capacity))

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
        replies = self.session.get(
            key,
            payload=body,
            encoding=JSON_ENCODING,
            timeout=timeout,
            consolidation=zenoh.ConsolidationMode.NONE,
        )
        for reply in replies:
            if reply.ok is not None:
                return _parse_reply(key, reply.ok.payload.to_bytes())
            error = reply.err.payload.to_string() if reply.err is not None else ""
            if error != TIMEOUT_REPLY:
                raise ServiceError(f"{key}: {error}")
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


def _answer_empty(query: zenoh.Query) -> None:
    with query:
        query.reply(query.key_expr, b"{}", encoding=JSON_ENCODING)


def _parse_reply(key: str, data: bytes) -> dict[str, Any]:
    try:
        value = json.loads(data)
    except (UnicodeDecodeError, ValueError):
        raise ServiceError(f"{key}: the reply is not JSON") from None
    if not isinstance(value, dict):
        raise ServiceError(f"{key}: the reply is a JSON {type(value).__name__}, not an object")
    return value
