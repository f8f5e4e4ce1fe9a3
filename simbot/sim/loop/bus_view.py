"""What systems may do on the bus: publish, and take commands that the loop drains and checks.

`SimBus` is a system's view of the server's node (scoped to its model's namespace); `Input` queues
a key's commands in a bus callback and decodes and checks them in the loop; `Drops` counts what
was refused, per key, for world state.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from simbot.bus import DecodeError, Node, Publisher, RosService, decode
from simbot.bus.frames import prefixed_frame
from simbot.bus.node import Refused, WarningPolicy
from simbot.bus.rmw import NodeName

log = logging.getLogger(__name__)

WARN_INTERVAL_S = 1.0
"""At most one warning per key and second about dropped input: a flood must not flood the log."""


@dataclass
class Drops:
    """Dropped inputs per key, with the last reason: world control's `state` reports them."""

    counts: dict[str, int] = field(default_factory=dict)
    last_error: dict[str, str] = field(default_factory=dict)
    _last_warning: dict[str, float] = field(default_factory=dict)

    def drop(self, key: str, reason: str, count: int = 1, warning: WarningPolicy = "rate-limited") -> None:
        """Counts dropped inputs and warns, rate-limited per key (or `always`, or `none`: counts only)."""
        self.counts[key] = self.counts.get(key, 0) + count
        self.last_error[key] = reason
        now = time.monotonic()
        due = now - self._last_warning.get(key, -math.inf) >= WARN_INTERVAL_S
        if warning == "always" or (warning == "rate-limited" and due):
            self._last_warning[key] = now
            log.warning("dropped input on %s (%d so far): %s", key, self.counts[key], reason)


Check = Callable[[Any], "str | None"]
"""Returns why a decoded message is unacceptable, or None."""


class Doorbell:
    """The systems of one kind in a world that have something to do: rung by their inputs when a
    message comes (on the bus's thread) and by themselves while they still work (a drive that
    ramps), so that their batch steps those alone, not a fleet's thousand at every step. Answered
    in the order the systems joined (a run does not depend on the order messages came in)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rung: set[Any] = set()
        self._order: dict[Any, int] = {}

    def join(self, owner: Any) -> None:
        """`owner` may ring from now on; it is rung once, for its first step."""
        with self._lock:
            self._order.setdefault(owner, len(self._order))
            self._rung.add(owner)

    def ring(self, owner: Any) -> None:
        with self._lock:
            if owner in self._order:
                self._rung.add(owner)

    def answer(self) -> list[Any]:
        """Who rang since the last answer, each once, in the order they joined."""
        if not self._rung:  # most steps: no one (a length read needs no lock)
            return []
        with self._lock:
            rung, self._rung = self._rung, set()
        return sorted(rung, key=self._order.__getitem__)

    def leave(self, owner: Any) -> None:
        """`owner` left the world: a ring already in is dropped."""
        with self._lock:
            self._order.pop(owner, None)
            self._rung.discard(owner)


class Input:
    """Commands on one key: queued by the bus, decoded and checked in the loop; bad ones dropped and counted."""

    def __init__(
        self,
        node: Node,
        drops: Drops,
        topic: str,
        typename: str,
        check: Check | None = None,
        ros_node: NodeName | None = None,
    ) -> None:
        self.key = node.key(topic)
        self._inbox = node.inbox(topic, typename, ros_node=ros_node)
        self._drops = drops
        self._typename = typename
        self._check = check
        self._overflowed = 0
        self._bell: tuple[Doorbell, Any] | None = None

    @property
    def received(self) -> int:
        """Payloads that reached the server on this key, valid or not, drained or not."""
        return self._inbox.received

    def rings(self, bell: Doorbell, owner: Any) -> None:
        """Each message that comes rings `bell` for `owner` (the system that drains this input)."""
        bell.join(owner)
        self._bell = (bell, owner)
        self._inbox.on_arrival = partial(bell.ring, owner)

    def close(self) -> None:
        self._inbox.close()
        if self._bell is not None:
            self._inbox.on_arrival = None
            self._bell[0].leave(self._bell[1])

    @property
    def pending(self) -> bool:
        """Whether anything arrived since the last drain: a fleet's systems pass over an empty input
        without draining it."""
        return self._inbox.pending

    def drain(self) -> list[Any]:
        """The valid messages that arrived since the last call, oldest first."""
        if self._inbox.overflowed != self._overflowed:
            lost, self._overflowed = self._inbox.overflowed - self._overflowed, self._inbox.overflowed
            self._drops.drop(
                self.key, "more commands arrived within one step than the queue holds; the oldest were dropped", lost
            )
        messages = []
        for payload in self._inbox.drain():
            if isinstance(payload, Refused):
                self._drops.drop(self.key, payload.reason, warning=payload.warning)
                continue
            try:
                message = decode(payload, self._typename) if isinstance(payload, bytes) else payload
            except DecodeError as exc:
                self._drops.drop(self.key, f"not a {self._typename}: {exc}")
                continue
            problem = self._check(message) if self._check else None
            if problem:
                self._drops.drop(self.key, problem)
                continue
            messages.append(message)
        return messages


@dataclass
class SimBus:
    """What systems may do on the bus: publish, and take commands through an `Input`.

    `scoped(namespace)` gives the view one model's systems get: its keys under the namespace
    (`tug_2/cmd_vel`), the frame ids of what it publishes prefixed (`tug_2/base_link`), and what
    it declared undeclared together by `close()` when the model leaves the world."""

    node: Node
    drops: Drops = field(default_factory=Drops)
    inputs: list[Input] = field(default_factory=list)
    doorbells: dict[str, Doorbell] = field(default_factory=dict)
    """The world's doorbells, one a kind of system (`doorbell`)."""
    namespace: str = ""
    ros_node: NodeName | None = None
    """The robot's own node on the graph, which announces what this view declares (None: the server's)."""
    _declared: list[Publisher | Input | RosService] = field(default_factory=list)

    def scoped(self, namespace: str) -> SimBus:
        """A view for one model's systems (`namespace` empty: the world's keys and frames; else a
        robot's, announced by a node of its own); shares the dropped-input counters and the list of
        inputs world state reports."""
        robot = self.node.robot_node(namespace) if namespace else None
        return SimBus(self.node, self.drops, self.inputs, self.doorbells, namespace, robot)

    def doorbell(self, kind: str) -> Doorbell:
        """The world's doorbell for systems of `kind` (their class: every view of the world gives the same)."""
        return self.doorbells.setdefault(kind, Doorbell())

    def topic(self, topic: str) -> str:
        return f"{self.namespace}/{topic}" if self.namespace else topic

    def frame(self, frame: str) -> str:
        """`frame` as this view's publishers send it (`tug_2/base_scan_front`): a system that names its
        frames so once spares every message the publisher's copy (`with_frame_prefix`)."""
        return prefixed_frame(frame, self.namespace)

    def publisher(self, topic: str, msgtype: type[Any], *, latched: bool = False) -> Publisher:
        """A publisher of `msgtype` (a `messages` class) on `topic`, on the graph from the start,
        that encodes and sends nothing while no subscriber matches it (its system can ask
        `has_subscribers` before it builds a message)."""
        publisher = self.node.publisher(
            self.topic(topic),
            msgtype,
            latched=latched,
            frame_prefix=self.namespace,
            watched_only=True,
            ros_node=self.ros_node,
        )
        self._declared.append(publisher)
        return publisher

    def ros_service(self, name: str, typename: str) -> RosService:
        """A ROS 2 service (`std_srvs/srv/Empty`...) at `name` in this view, polled by its system."""
        service = self.node.ros_service(self.topic(name), typename, ros_node=self.ros_node)
        self._declared.append(service)
        return service

    def input(self, topic: str, typename: str, check: Check | None = None) -> Input:
        self.inputs.append(Input(self.node, self.drops, self.topic(topic), typename, check, self.ros_node))
        self._declared.append(self.inputs[-1])
        return self.inputs[-1]

    def close(self) -> None:
        """Undeclares every key this view declared: they leave the graph."""
        for entity in self._declared:
            entity.close()
            if isinstance(entity, Input):
                self.inputs.remove(entity)
        self._declared.clear()
        if self.ros_node is not None:
            self.node.release_robot_node(self.namespace)
