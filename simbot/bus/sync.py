"""Messages of several streams grouped by stamp, like ROS's ApproximateTime synchroniser.

The lidar merger pairs the front and back scans, the camera stitcher groups six images. A set
is one message per stream whose stamps lie within `slop` of each other; when it is complete it
comes out of `add` at once. A stream that falls silent must not hold the others back: once the
newest stamp seen on any stream is more than `max_wait` past a waiting message, that message
comes out in a partial set, with None for the streams that had nothing close enough.

Stamps are sim time. A stamp older than the newest already seen on its stream means the world
was reset or the server restarted (sim time began again): everything waiting is forgotten, and
with it the newest stamp of every stream, so that grouping starts afresh with the first message of
each stream in the new run (which is older than that stream's last in the old one too).
`add` is thread-safe (Zenoh calls it from its threads) and does no work beyond the grouping, so
the sets it returns should be handed to the client's own loop.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Generic, TypeVar

M = TypeVar("M")


class StampSync(Generic[M]):
    """Groups (stream, stamp, message) arrivals into sets of one message per stream."""

    def __init__(self, streams: Sequence[str], slop_ns: int, max_wait_ns: int, depth: int = 16) -> None:
        if len(set(streams)) != len(streams) or not streams:
            raise ValueError(f"streams must be distinct and not empty: {list(streams)}")
        if slop_ns < 0 or max_wait_ns < slop_ns:
            raise ValueError(f"need 0 ≤ slop ({slop_ns} ns) ≤ max_wait ({max_wait_ns} ns)")
        self.streams = tuple(streams)
        self.slop_ns = slop_ns
        self.max_wait_ns = max_wait_ns
        self.depth = depth
        self.partial_sets = 0
        """Sets that came out incomplete."""
        self.resets = 0
        """Times the stamps went back (world resets, server restarts)."""
        self._queues: dict[str, list[tuple[int, M]]] = {s: [] for s in self.streams}
        self._newest: dict[str, int] = {}
        """The newest stamp seen on each stream in this run (the queues lose theirs as sets are taken)."""
        self._lock = threading.Lock()

    def add(self, stream: str, stamp_ns: int, msg: M) -> list[dict[str, M | None]]:
        """Queue a message; the sets it completes (and partial ones it makes overdue), oldest first."""
        if stream not in self._queues:
            raise KeyError(f"unknown stream {stream!r} (streams: {', '.join(self.streams)})")
        with self._lock:
            if stamp_ns < self._newest.get(stream, stamp_ns):
                self.resets += 1
                self._newest.clear()
                for waiting in self._queues.values():
                    waiting.clear()
            self._newest[stream] = stamp_ns
            queue = self._queues[stream]
            if queue and queue[-1][0] == stamp_ns:
                queue[-1] = (stamp_ns, msg)  # the same stamp again: the newer message wins
            else:
                queue.append((stamp_ns, msg))
                del queue[: -self.depth]
            sets = []
            complete = self._complete_around(stamp_ns)
            if complete is not None:
                sets.append(complete)
            while (overdue := self._overdue()) is not None:
                sets.append(overdue)
            return sets

    def _nearest(self, stream: str, stamp_ns: int) -> tuple[int, M] | None:
        """The message of `stream` whose stamp is nearest `stamp_ns`, if within slop."""
        best = min(self._queues[stream], key=lambda item: abs(item[0] - stamp_ns), default=None)
        if best is None or abs(best[0] - stamp_ns) > self.slop_ns:
            return None
        return best

    def _take(self, chosen: dict[str, tuple[int, M] | None]) -> dict[str, M | None]:
        """Remove the chosen messages and everything older on their streams; the set of messages."""
        for stream, item in chosen.items():
            if item is not None:
                self._queues[stream] = [q for q in self._queues[stream] if q[0] > item[0]]
        return {stream: (item[1] if item is not None else None) for stream, item in chosen.items()}

    def _complete_around(self, stamp_ns: int) -> dict[str, M | None] | None:
        chosen = {stream: self._nearest(stream, stamp_ns) for stream in self.streams}
        items = [item for item in chosen.values() if item is not None]
        if len(items) < len(self.streams):
            return None
        stamps = [stamp for stamp, _ in items]
        if max(stamps) - min(stamps) > self.slop_ns:
            return None
        return self._take(chosen)

    def _overdue(self) -> dict[str, M | None] | None:
        """A partial set around the oldest waiting message, once the newest stamp is max_wait past it."""
        waiting = [queue[0][0] for queue in self._queues.values() if queue]
        newest = max((queue[-1][0] for queue in self._queues.values() if queue), default=None)
        if not waiting or newest is None or newest - min(waiting) <= self.max_wait_ns:
            return None
        oldest = min(waiting)
        chosen = {stream: self._nearest(stream, oldest) for stream in self.streams}
        self.partial_sets += 1
        return self._take(chosen)
