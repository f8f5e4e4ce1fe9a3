"""Raw CDR samples of published keys, checked and typed: what the recorder and the Foxglove bridge carry.

Both pass payloads on unchanged (a bag and a WebSocket client want the bytes the server wrote),
so the tap does not hand out decoded messages. It still decodes each payload once to check it: a
malformed message on the bus (garbage, or a sample whose encoding names another type than the
graph announces) is dropped and counted, never written into a bag or sent to a viewer.

Every key is tapped through a Zenoh advanced subscriber asking for history, so a latched key
(`tf_static`, `robot_description`) reaches a recorder started after the server, as `ros2 bag
record` gets transient-local topics.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from simbot.bus import DecodeError, Node, UnknownMessageType, decode, messages
from simbot.bus.node import RateLimitedWarnings

from .topics import Topic, live_topics, schema_type

logger = logging.getLogger(__name__)


class MalformedSample(ValueError):
    """A payload that cannot go on as a message of its topic's type; str() says why."""


@dataclass(frozen=True)
class RawSample:
    """One checked payload: its topic name (without the namespace), its ROS 2 type, its CDR bytes,
    when it arrived (wall clock, ns since the epoch, as rosbag2 stamps what it records), and its
    sim time (ns: the header stamp, or a Clock's time; None for a message with neither), read while checking it."""

    topic: str
    typename: str
    data: bytes
    received_ns: int
    stamp_ns: int | None = None


def published(node: Node) -> dict[str, Topic]:
    """The live topics of the node's namespace that someone publishes, by topic name."""
    return {name: topic for name, topic in live_topics(node).items() if "pub" in topic.kinds}


class Tap:
    """Subscriptions to chosen topics that hand each checked sample to `deliver` (on a Zenoh thread)."""

    def __init__(self, node: Node, deliver: Callable[[RawSample], None]) -> None:
        self._node = node
        self._deliver = deliver
        self._warnings = RateLimitedWarnings()
        self._lock = threading.Lock()
        self._subscribers: dict[str, zenoh.ext.AdvancedSubscriber] = {}
        self.dropped: dict[str, int] = {}

    def listen(self, topic: Topic) -> None:
        """Start tapping `topic` (nothing when it is tapped already)."""
        if topic.name in self._subscribers:
            return
        history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1)
        self._subscribers[topic.name] = zenoh.ext.declare_advanced_subscriber(
            self._node.session, topic.data_key, lambda sample: self._on_sample(topic, sample), history=history
        )

    def unlisten(self, name: str) -> None:
        """Stop tapping the topic `name` (nothing when it is not tapped)."""
        subscriber = self._subscribers.pop(name, None)
        if subscriber is not None:
            subscriber.undeclare()

    def _on_sample(self, topic: Topic, sample: zenoh.Sample) -> None:
        """Zenoh thread: check the sample against its topic's type, then deliver it or count it."""
        if sample.kind != zenoh.SampleKind.PUT:
            return
        data = sample.payload.to_bytes()
        try:
            msg = check(topic, data, str(sample.encoding))
        except MalformedSample as exc:
            with self._lock:
                self.dropped[topic.name] = self.dropped.get(topic.name, 0) + 1
            self._warnings.warn(topic.key, f"dropped a sample: {exc}")
            return
        try:
            self._deliver(RawSample(topic.name, topic.typename, data, time.time_ns(), sim_time_ns(msg)))
        except Exception:
            logger.exception("%s: delivering a sample failed", topic.key)

    def close(self) -> None:
        """Stop tapping every topic."""
        for name in list(self._subscribers):
            self.unlisten(name)


def check(topic: Topic, data: bytes, encoding: str) -> Any:
    """The message a payload holds, decoded once to prove it is one of the topic's type; MalformedSample otherwise."""
    named = schema_type(encoding)
    if named is not None and named != topic.typename:
        raise MalformedSample(f"its encoding names {named}, the topic carries {topic.typename}")
    try:
        return decode(data, topic.typename)
    except DecodeError as exc:
        raise MalformedSample(f"not a valid {exc}") from None
    except UnknownMessageType as exc:
        raise MalformedSample(str(exc)) from None


def sim_time_ns(msg: Any) -> int | None:
    """The sim time a message carries: its header stamp, or a rosgraph_msgs/Clock's time; None for neither."""
    stamped = getattr(msg, "header", None) or getattr(msg, "clock", None)
    try:
        return None if stamped is None else messages.stamp_ns(stamped)
    except TypeError:  # a field named so that is not a Header or a Time
        return None
