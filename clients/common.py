"""What every client program does the same way: its command line, its bus session, its stop.

A client parses its options (the bus options of every simbot program, plus its own), opens a
Zenoh *client* session (connecting to the server, listening on nothing), and runs its body until
the body returns or SIGINT / SIGTERM sets `stop`. A user's mistake (a bad option, a bad Zenoh
config, no server to connect to) is one line on stderr and exit code 2, never a traceback.

Zenoh calls subscription callbacks on its own threads; clients hand messages to their main loop
through a `Mailbox` and do their work there. Two things several clients need are built on it:
`StaticTransforms` (sensor poses from the latched `tf_static`, as a ROS node reads tf) and
`StampedSets` (messages of several topics grouped by stamp, e.g. the lidars or the cameras).

A client stays up when the server goes: its Zenoh client session reconnects by itself to its
`--connect` endpoint, however long the server is away, and its subscriptions and publishers carry
on. Sim time then starts again from zero, as after a world reset; every client watches the clock
through `SimTimeWatch` (in `ClockSubscriber`, or fed by the client's own clock samples), which
logs one line per jump back so the user knows the data before and after belong to different runs.
"""

from __future__ import annotations

import argparse
import functools
import logging
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, Subscription, add_bus_arguments, messages
from simbot.bus.frames import frame_prefix, prefixed_frame
from simbot.bus.sync import StampSync
from simbot.bus.tf_tree import Matrix, TransformTree

logger = logging.getLogger(__name__)

EXIT_USAGE = 2
CLOCK = "rosgraph_msgs/msg/Clock"
POLL_S = 0.02
"""How long a client waiting for sim time to pass waits at a time (wall clock)."""
T = TypeVar("T")

ClientBody = Callable[[argparse.Namespace, Node, threading.Event], int]
"""The client's work: (its options, its bus node, the stop event) → exit code."""


class ClientError(Exception):
    """A user's mistake found after parsing (a key that does not exist, a file that cannot be written)."""


def client_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A parser with `-v` and the bus options; the client adds its own arguments."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    add_bus_arguments(parser)
    parser.add_argument(
        "--robot-namespace",
        default="",
        metavar="NS",
        help="the robot's namespace within the bus's (a model created in one, tug_2 of --robots N): "
        "its topics under NS, the clock and world control where they are",
    )
    return parser


def followed_model(robot_namespace: str, default: str = "flexley_tug") -> str:
    """The model name of the robot a client follows: the last segment of its `--robot-namespace`
    (`tug_2`, as `--robots N` names each tug after its namespace), else `default`, the one robot's."""
    return robot_namespace.strip("/").rpartition("/")[2] or default


def run_client(
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None,
    body: ClientBody,
    check: Callable[[], object] | None = None,
) -> int:
    """Parse, run `check` (a precondition that raises ClientError), open the bus, run `body` until it
    returns or a signal asks to stop; the exit code."""
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s"
    )
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        if check is not None:
            check()
        with Node(BusOptions.from_args(args), "client") as node:
            return body(args, node, stop)
    except (BusConfigError, BusOpenError, ClientError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


class Mailbox(Generic[T]):
    """Items from Zenoh threads to the main loop; holds the newest `size`, counts what it let go."""

    def __init__(self, size: int = 1) -> None:
        self._items: deque[T] = deque(maxlen=size)
        self._ready = threading.Condition()
        self.overwritten = 0

    def put(self, item: T) -> None:
        """Queue `item` (the oldest goes when full) and wake the loop."""
        with self._ready:
            if len(self._items) == self._items.maxlen:
                self.overwritten += 1
            self._items.append(item)
            self._ready.notify()

    def get(self, timeout: float) -> T | None:
        """The oldest queued item, waiting up to `timeout` seconds; None when nothing came."""
        with self._ready:
            if not self._items:
                self._ready.wait(timeout)
            return self._items.popleft() if self._items else None


class StatusLine:
    """A line of figures on stderr: redrawn in place once a second on a terminal, printed every few
    seconds elsewhere (a log file, `simbot launch`), so that a log is not flooded."""

    def __init__(self, period_s: float = 1.0, plain_period_s: float = 5.0) -> None:
        self.live = sys.stderr.isatty()
        self._period_s = period_s if self.live else plain_period_s
        self._next = time.monotonic() + self._period_s

    def show(self, now: float, text: Callable[[], str]) -> None:
        """Print `text()` when a period has passed since the last line (`now` from time.monotonic())."""
        if now < self._next:
            return
        self._next = now + self._period_s
        line = text()
        print(f"\r\x1b[2K{line}" if self.live else line, end="" if self.live else "\n", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class TimeJump:
    """Sim time going back: from the latest time seen to an earlier one, noticed at `wall_ns` (time.time_ns())."""

    from_ns: int
    to_ns: int
    wall_ns: int


class SimTimeWatch:
    """The sim times of one source (the clock) watched for going back: the server restarted or the
    world was reset, and what came before belongs to another run.

    Within one run sim time only goes forward (paused, it stands), so any earlier time than the
    latest seen is a jump. Each is logged once, as one warning line, and handed to `on_jump` (on the
    caller's thread, a Zenoh one: it should only queue). Thread-safe.
    """

    def __init__(self, on_jump: Callable[[TimeJump], None] | None = None) -> None:
        self._on_jump = on_jump
        self._lock = threading.Lock()
        self._latest: int | None = None
        self.jumps = 0

    def see(self, ns: int) -> TimeJump | None:
        """Take the source's next sim time (ns); the jump when it went back, else None."""
        with self._lock:
            latest, self._latest = self._latest, ns
            if latest is None or ns >= latest:
                return None
            self.jumps += 1
        jump = TimeJump(latest, ns, time.time_ns())
        logger.warning(
            "sim time went back from %.3f s to %.3f s: the server restarted or the world was reset",
            latest / 1e9,
            ns / 1e9,
        )
        if self._on_jump is not None:
            self._on_jump(jump)
        return jump


class ClockSubscriber:
    """Sim time from `clock`, in seconds: what the clients' freshness windows, docking checks and
    teleop ticks count, so that a world running at 0.5× or 4× (or paused, or stepped) behaves the same.

    A client that waits does so in short slices of wall time (`POLL_S`) and compares sim times.
    The clock going back (a restart, a reset) is logged once by its `watch`, and given to `on_jump`.
    """

    def __init__(self, node: Node, on_jump: Callable[[TimeJump], None] | None = None) -> None:
        self._lock = threading.Lock()
        self._ns: int | None = None
        self.watch = SimTimeWatch(on_jump)
        node.subscribe("/clock", CLOCK, self._tick)  # the world's, whatever robot the client follows

    def _tick(self, msg: Any) -> None:
        ns = messages.stamp_ns(msg.clock)
        with self._lock:
            self._ns = ns
        self.watch.see(ns)

    def now(self) -> float | None:
        """The latest sim time (s), or None before the first clock."""
        with self._lock:
            return None if self._ns is None else self._ns / 1e9


class SimTicker:
    """A period of sim time: due at the first clock and a period after each time it was; a world
    reset (sim time going back) makes it due at once."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._began: float | None = None

    def due(self, now: float | None) -> bool:
        """Whether a period has passed at sim time `now` (never before the first clock); if so, the next begins."""
        if now is None:
            return False
        if self._began is not None and self._began <= now < self._began + self.period_s:
            return False
        self._began = now
        return True

    def restart(self, now: float | None) -> None:
        """The next period begins at `now` (an action taken out of turn)."""
        self._began = now


class Recent:
    """The latest message of one stamped topic while it is fresh: queued by Zenoh, read by the loop.

    A keyboard client acting on stale data (a lidar that fell silent, a pose from a second ago)
    would act on a world that has moved on, so a message whose header stamp is more than
    `max_age_s` of sim time before now counts as none; so does one stamped more than that after
    now, which came before the clock went back (a server restarted, a world reset), from another run.
    """

    def __init__(self, node: Node, topic: str, typename: str, max_age_s: float) -> None:
        self.max_age_s = max_age_s
        self._inbox: Mailbox[Any] = Mailbox()
        self._latest: Any | None = None
        node.subscribe(topic, typename, self._inbox.put)

    def get(self, now: float | None) -> Any | None:
        """The latest message, or None when none is stamped within `max_age_s` of `now` (sim time, s; None: no clock yet)."""
        arrived = self._inbox.get(timeout=0.0)
        if arrived is not None:
            self._latest = arrived
        if self._latest is None or now is None:
            return None
        if abs(now - messages.stamp_ns(self._latest.header) / 1e9) > self.max_age_s:
            return None
        return self._latest


class StaticTransforms:
    """Poses of frames in one target frame, from the latched `tf_static`: queued by Zenoh, taken in by `refresh`.

    The target is that of the frame's own robot: `base_link` for `base_scan_front`, `tug_2/base_link`
    for `tug_2/base_scan_front` (a robot in a namespace of its own prefixes its frames)."""

    def __init__(self, node: Node, target: str) -> None:
        self.target = target
        self._tree = TransformTree()
        self._inbox: Mailbox[Any] = Mailbox(size=16)
        self._poses: dict[str, Matrix | None] = {}
        node.subscribe("tf_static", "tf2_msgs/msg/TFMessage", self._inbox.put, latched=True)

    def refresh(self) -> bool:
        """Take in the tf_static messages that came (in the loop); True when any did, so cached poses are gone."""
        changed = False
        while (tf := self._inbox.get(0.0)) is not None:
            self._tree.update(tf)
            changed = True
        if changed:
            self._poses.clear()
        return changed

    def pose(self, frame: str) -> Matrix | None:
        """The matrix mapping `frame` into the target (cached until tf_static changes); None while not connected.

        ValueError when tf_static holds a cycle.
        """
        if frame not in self._poses:
            self._poses[frame] = self._tree.lookup(self.target_of(frame), frame)
        return self._poses[frame]

    def rooted(self, frame: str) -> tuple[str, Matrix] | None:
        """(the root of `frame`'s tree, `frame`'s pose in it), or None while tf_static does not name `frame`."""
        return self._tree.rooted(frame) if frame in self._tree.frames else None

    def target_of(self, frame: str) -> str:
        """The target frame in the tree of `frame`'s robot."""
        return prefixed_frame(self.target, frame_prefix(frame))


class StampedSets:
    """Messages of several topics grouped by header stamp (StampSync) on Zenoh's threads, taken by the loop as sets."""

    def __init__(
        self, node: Node, topics: Sequence[str], typename: str, slop_ns: int, max_wait_ns: int, queue: int
    ) -> None:
        self.sync: StampSync[Any] = StampSync(topics, slop_ns, max_wait_ns)
        self._sets: Mailbox[dict[str, Any]] = Mailbox(size=queue)
        self._inputs: list[Subscription[Any]] = [
            node.subscribe(topic, typename, functools.partial(self._receive, topic)) for topic in topics
        ]

    def _receive(self, topic: str, msg: Any) -> None:
        for ready in self.sync.add(topic, messages.stamp_ns(msg.header), msg):
            self._sets.put(ready)

    def get(self, timeout: float) -> dict[str, Any] | None:
        """The next set ({topic: message or None when it had no partner}), waiting up to `timeout` seconds."""
        return self._sets.get(timeout)

    @property
    def undecodable(self) -> int:
        """Payloads that were not of the type (dropped and counted by the subscriptions)."""
        return sum(s.dropped for s in self._inputs)

    @property
    def overwritten(self) -> int:
        """Sets that came faster than the loop took them, and were let go."""
        return self._sets.overwritten
