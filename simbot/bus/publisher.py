"""A publisher on one key: rmw_zenoh's attachment, latched topics served to late joiners, and
who listens known without asking.

Zenoh's matching listener tells the publisher when a first subscriber comes and the last one
leaves, so `has_subscribers` is an attribute read: a server with a hundred tugs asks it thousands
of times a step (every camera, every IMU). A node's `Watching` counts those changes of all its
publishers, so that a system serving thousands (a fleet's cameras) asks them again only after one.
A `watched_only` publisher (the server's) neither encodes nor sends what no one matches.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import zenoh
import zenoh.ext

from simbot.bus.codec import encode
from simbot.bus.frames import with_frame_prefix
from simbot.bus.graph import Announcement
from simbot.bus.rmw import Attachments
from simbot.bus.services import undeclare

CDR_ENCODING = zenoh.Encoding.APPLICATION_CDR
T = TypeVar("T")


def direct(callback: Callable[[T], None]) -> zenoh.handlers.Callback[T]:
    """`callback` run on the Zenoh thread that has the news, for a callback that only records it
    (a flag, a queue, a copy): zenoh-python otherwise starts a Python thread for every callback
    declared, 28 a tug (measured: 7008 threads for 250 tugs, and declaring them took most of a
    fleet's start)."""
    return zenoh.handlers.Callback(callback, indirect=False)


class Watching:
    """How many times any of a node's publishers learnt that a first subscriber came or the last
    one left: what its publishers' `has_subscribers` say holds while `generation` does."""

    def __init__(self) -> None:
        self._changes = itertools.count(1)
        self.generation = 0

    def changed(self) -> None:
        """A publisher's subscribers changed (any thread: `next` on a count is one step)."""
        self.generation = next(self._changes)


@dataclass(frozen=True)
class Route:
    """Where one entity of a node goes: its topic's name within simbot (`ns/odom`), its data key,
    the type it carries and the graph token that announces it (None: off the graph)."""

    name: str
    key: str
    typename: str
    token: str | None


class Publisher:
    """Encodes messages and puts them on one key with rmw_zenoh's attachment; latched publishers
    also serve the latest to late joiners. On the graph from its declaration."""

    def __init__(
        self,
        session: zenoh.Session,
        route: Route,
        *,
        latched: bool,
        drop: bool,
        frame_prefix: str = "",
        watched_only: bool = False,
        listening: bool = True,
        watching: Watching | None = None,
    ) -> None:
        """`listening=False`: who listens is followed only after `listen`, taken to be someone
        until then (a server declares its world's publishers first, then listens:
        `Node.listening_later`); `watching` counts each change of who listens (the node's)."""
        self.key = route.name
        self.data_key = route.key
        self.typename = route.typename
        self.frame_prefix = frame_prefix
        """Every frame id the messages carry goes out under it (`frames.with_frame_prefix`)."""
        self.latched = latched
        self._encoding = CDR_ENCODING.with_schema(route.typename)
        """`application/cdr;TYPE`: lets a monitor decode a key without being told its type."""
        self._attachments = Attachments()
        self._announcement = Announcement(session, route.token) if route.token else None
        congestion = zenoh.CongestionControl.DROP if drop and not latched else zenoh.CongestionControl.BLOCK
        self._latest: bytes | None = None
        self._lock = threading.Lock()
        self._queryable: zenoh.Queryable[None] | None = None
        self._listener: zenoh.MatchingListener[None] | None = None
        self._matching = True
        self._recheck = False
        self._watching = watching or Watching()
        self._closed = False
        self._watched_only = watched_only and not latched
        self._publisher: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        if latched:  # rmw_zenoh's TRANSIENT_LOCAL: an advanced publisher with a cache, and a plain `get`'s answer
            self._publisher = zenoh.ext.declare_advanced_publisher(
                session,
                route.key,
                encoding=self._encoding,
                congestion_control=congestion,
                cache=zenoh.ext.CacheConfig(1),
                publisher_detection=True,
            )
            self._queryable = session.declare_queryable(route.key, direct(self._serve_latest), complete=True)
        else:
            self._publisher = session.declare_publisher(
                route.key, encoding=self._encoding, congestion_control=congestion
            )
            if listening:
                self.listen()

    def listen(self) -> None:
        """From now on Zenoh's matching listener says when a first subscriber comes and the last one
        leaves (a plain publisher's; a latched one always serves). Zenoh matches every subscriber
        declared later against every listener: a thousand tugs' publishers listening while their
        inboxes are declared cost 7 ms an inbox, listening after them 0.2 ms a publisher (measured)."""
        if self._closed or self._listener is not None or not isinstance(self._publisher, zenoh.Publisher):
            return  # closed while the world loaded (a model whose systems failed), or listening already
        self._listener = self._publisher.declare_matching_listener(direct(self._on_matching))
        self._matching = _matching(self._publisher.matching_status)
        self._watching.changed()

    def _on_matching(self, status: zenoh.MatchingStatus) -> None:
        """Zenoh thread: a first subscriber came, or the last one left. The news can come late, after
        a newer status the publisher read itself (`refresh`), so "none" only makes it ask its session
        again when next asked (not here: the publisher may be closing on the loop's thread)."""
        if _matching(status):
            self._matching = True
        else:
            self._recheck = True
        self._watching.changed()

    def refresh(self) -> bool:
        """Asks Zenoh now whether a subscriber came: the listener hears of it a little after the
        session does (14 of 100 times measured, after a query that followed the declaration on the
        same link), and a step request must see every subscriber declared before it. False once
        closed, and for a latched publisher (it always serves); True for one not listening yet
        (`listening=False`: taken to be watched until `listen`)."""
        if self._closed or self.latched:
            return False
        if self._listener is None:
            return True
        return self._matching or self._ask()

    def _ask(self) -> bool:
        """The session's matching status, kept; False once closed."""
        if self._listener is None or not isinstance(self._publisher, zenoh.Publisher):
            return False
        try:
            matching = _matching(self._publisher.matching_status)
        except zenoh.ZError:  # undeclared by close() on another thread
            return False
        if matching != self._matching:
            self._matching = matching
            self._watching.changed()
        return True

    def put(self, msg: Any) -> None:
        """Encode `msg` as CDR and put it. A `watched_only` publisher that no subscriber matches
        does neither: the server's, declared long before any subscriber, whose session would route
        the put nowhere. (A fresh publisher's session may still be learning who subscribes, and
        Zenoh delivers its first puts to the peers it knows: a client's keep that.)"""
        if not self._watched_only or self.has_subscribers:
            self._put(encode(with_frame_prefix(msg, self.frame_prefix) if self.frame_prefix else msg))

    def put_raw(self, data: bytes | bytearray) -> None:
        """Put bytes as they are, as CDR of the publisher's type: a recording played back goes out
        unchanged, a render worker's image encoded in place, and tests send garbage this way. (A
        latched publisher keeps a copy of its own.)"""
        self._put(bytes(data) if self.latched else data)

    def _put(self, data: bytes | bytearray) -> None:
        if self.latched:
            with self._lock:
                self._latest = bytes(data)
        self._publisher.put(data, encoding=self._encoding, attachment=self._attachments.next())

    def _serve_latest(self, query: zenoh.Query) -> None:
        """Plain `get` on a latched key: reply with the latest payload (called on a Zenoh thread)."""
        with query:
            with self._lock:
                latest = self._latest
            if latest is not None:
                query.reply(self.data_key, latest, encoding=self._encoding, attachment=self._attachments.next())

    @property
    def has_subscribers(self) -> bool:
        """Whether a subscriber matching the key is known (plain publishers only; latched ones say
        True). Zenoh's matching listener keeps it, so asking costs an attribute read: a camera
        no one watches is asked every tick."""
        if self._recheck:
            self._recheck = False
            self._ask()
        return self._matching

    def await_subscribers(self, timeout: float) -> bool:
        """Whether `has_subscribers` came true within `timeout` s: a session learns of a subscriber
        some time after another session declared it, and Zenoh's publisher may drop a put for a
        subscriber its session has not heard of yet."""
        deadline = time.monotonic() + timeout
        pause = 1e-4
        while not self.has_subscribers:
            self.refresh()  # the session's own view, not the listener's later news of it
            if self.has_subscribers:
                break
            if time.monotonic() >= deadline:
                return False
            time.sleep(pause)
            pause = min(2 * pause, 0.01)
        return True

    def close(self) -> None:
        """Undeclare the publisher (and the latched queryable)."""
        self._closed = True
        if self._announcement is not None:
            self._announcement.close()
        undeclare(self._listener)
        undeclare(self._queryable)
        undeclare(self._publisher)
        self._queryable = self._listener = None


def _matching(status: object) -> bool:
    """zenoh 1.10 gives a MatchingStatus (always truthy), though its stub says bool."""
    return bool(getattr(status, "matching", status))
