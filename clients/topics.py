"""`simbot topics`: the live keys with their type, who uses them, rate and bandwidth.

What `ros2 topic list -v` plus `ros2 topic hz` and `bw` give. The graph (`simbot.bus.graph`)
says which keys are live and what they carry, including inputs nobody publishes (`cmd_vel`) and
services (world control). Rates and bandwidth are measured by a raw Zenoh subscriber on
`<domain>/<namespace>/**` (rmw_zenoh's data keys) for `--window` seconds, whose callback only
counts arrival times and bytes.

Cameras render only while someone subscribes, but they are on the graph from the start (the
server's publishers announce their type when declared). Measuring subscribes to every key,
cameras included, so the camera rates are real, at the price of the server rendering for the
window (the render workers, once started, stay). `--window 0` measures nothing and renders
nothing: the graph alone.

A latched key (`robot_description`, `tf_static`, `detachable_joint/state`) publishes on change
only; the graph does not say it is latched, but a plain Zenoh `get` on it is answered (latched
publishers serve their latest message that way), so a silent key that answers reads "latched".

The rate counter (`Traffic`) and the graph lookups here are shared with `simbot echo` and
`simbot monitor`.
"""

from __future__ import annotations

import sys
import threading
import time
from collections import defaultdict, deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import zenoh

from simbot.arguments import number
from simbot.bus import Node
from simbot.bus.graph import KINDS, SERVICE_TYPE, Kind, discover
from simbot.bus.rmw import RosGraph

from .common import ClientError, client_parser, run_client

DEFAULT_WINDOW_S = 2.0
LATCH_QUERY_TIMEOUT_S = 0.5
CDR_PREFIX = "application/cdr;"
COLUMNS = ("KEY", "TYPE", "WHO", "RATE", "BANDWIDTH")
NOTHING = "-"


# --- the graph ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Topic:
    """What the graph says of one key: its topic name, the type it carries and who uses it."""

    name: str
    key: str
    """The topic's full name without its leading slash (`ns/odom`): the ROS topic, world state's key."""
    typename: str
    kinds: tuple[Kind, ...]
    data_key: str
    """Where its samples are on Zenoh (rmw_zenoh's key; a JSON service's own name)."""


def topic_name(key: str, namespace: str, graph: RosGraph | None = None) -> str:
    """The topic name of a key (a name, or a data key of `graph`'s domain) without the namespace prefix."""
    name = (graph or RosGraph()).name_of(key) or key
    prefix = namespace.strip("/")
    return name[len(prefix) + 1 :] if prefix and name.startswith(prefix + "/") else name


def live_topics(node: Node) -> dict[str, Topic]:
    """Every live key of the node's namespace, by topic name; the publishers' type wins over the others'."""
    by_key: dict[str, dict[Kind, str]] = defaultdict(dict)
    for endpoint in discover(node.session, node.namespace, graph=node.graph):
        by_key[endpoint.key].setdefault(endpoint.kind, endpoint.typename)
    topics = {}
    for key, kinds in by_key.items():
        name = topic_name(key, node.namespace)
        typename = next(kinds[kind] for kind in KINDS if kind in kinds)
        data_key = key if typename == SERVICE_TYPE else node.graph.data_key(key, typename)
        topics[name] = Topic(name, key, typename, tuple(kind for kind in KINDS if kind in kinds), data_key)
    return topics


def world_names(topics: Iterable[Topic]) -> list[str]:
    """The worlds whose control services are live (`world/<name>/state`)."""
    names = []
    for topic in topics:
        parts = topic.name.split("/")
        if "srv" in topic.kinds and len(parts) == 3 and parts[0] == "world" and parts[2] == "state":
            names.append(parts[1])
    return sorted(names)


def schema_type(encoding: str) -> str | None:
    """The ROS 2 type a sample's encoding names (`application/cdr;sensor_msgs/msg/Imu`), if it names one."""
    if not encoding.startswith(CDR_PREFIX):
        return None
    return encoding[len(CDR_PREFIX) :] or None


# --- rates ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Figures:
    """A key's traffic over the horizon: messages, their rate (None below two) and bytes per second."""

    count: int
    rate_hz: float | None
    bytes_per_s: float


class Traffic:
    """Arrival times and sizes of samples per key, kept for `horizon_s`: what `ros2 topic hz` and `bw` measure.

    `count` is what a Zenoh callback calls (it only appends under a lock); `figures` is read by the loop.
    """

    def __init__(self, horizon_s: float) -> None:
        self.horizon_s = horizon_s
        self._started = time.monotonic()
        self._lock = threading.Lock()
        self._arrivals: dict[str, deque[tuple[float, int]]] = defaultdict(deque)

    def count(self, key: str, nbytes: int = 0) -> None:
        """One sample of `nbytes` on `key`, now."""
        now = time.monotonic()
        with self._lock:
            arrivals = self._arrivals[key]
            arrivals.append((now, nbytes))
            while arrivals[0][0] < now - self.horizon_s:
                arrivals.popleft()

    def keys(self) -> list[str]:
        """Every key that had a sample."""
        with self._lock:
            return list(self._arrivals)

    def figures(self, key: str, now: float | None = None) -> Figures:
        """The rate as the mean interval between arrivals (as `ros2 topic hz`), the bandwidth over the horizon
        that ends `now` (by default, the present)."""
        now = time.monotonic() if now is None else now
        start = max(self._started, now - self.horizon_s)
        with self._lock:
            arrivals = [a for a in self._arrivals.get(key, ()) if start <= a[0] <= now]
        span = arrivals[-1][0] - arrivals[0][0] if arrivals else 0.0
        rate = (len(arrivals) - 1) / span if len(arrivals) > 1 and span > 0 else None
        return Figures(len(arrivals), rate, sum(n for _, n in arrivals) / max(now - start, 1e-9))


def format_rate(figures: Figures) -> str:
    """`200.0 Hz`; a single message is counted rather than rated."""
    if figures.rate_hz is not None:
        return f"{figures.rate_hz:.1f} Hz"
    return "1 msg" if figures.count == 1 else NOTHING


def format_bandwidth(bytes_per_s: float) -> str:
    """B/s, kB/s or MB/s (powers of 1000, as `ros2 topic bw`)."""
    for unit, scale in (("MB/s", 1e6), ("kB/s", 1e3)):
        if bytes_per_s >= scale:
            return f"{bytes_per_s / scale:.1f} {unit}"
    return f"{bytes_per_s:.0f} B/s"


# --- measuring ------------------------------------------------------------------------------


@dataclass
class Measurement:
    """What a raw subscriber on every key saw: the traffic and each key's encoding, until `ended`."""

    traffic: Traffic
    encodings: dict[str, str]
    ended: float | None = None

    def figures(self, key: str) -> Figures:
        """The key's figures over the window (however late they are asked for)."""
        return self.traffic.figures(key, self.ended)

    def on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh thread: count and remember the first encoding, nothing more."""
        key = str(sample.key_expr)
        self.traffic.count(key, len(sample.payload))
        if key not in self.encodings:
            self.encodings[key] = str(sample.encoding)


def measure(node: Node, window_s: float, stop: threading.Event) -> Measurement:
    """Counts every sample in the namespace for `window_s` seconds (less if `stop` is set)."""
    measurement = Measurement(Traffic(window_s), {})
    scope = "/".join(part for part in (str(node.graph.domain_id), node.namespace.strip("/"), "**") if part)
    subscriber = node.session.declare_subscriber(scope, measurement.on_sample)
    try:
        stop.wait(window_s)
    finally:
        subscriber.undeclare()
    measurement.ended = time.monotonic()
    return measurement


def latched(session: zenoh.Session, keys: Iterable[str]) -> set[str]:
    """The keys whose plain `get` is answered: latched publishers serve their latest message that way."""
    pending = {key: session.get(key, timeout=LATCH_QUERY_TIMEOUT_S) for key in keys}
    return {key for key, replies in pending.items() if any(reply.ok is not None for reply in replies)}


# --- the table ------------------------------------------------------------------------------


def table_rows(node: Node, measurement: Measurement | None) -> list[tuple[str, ...]]:
    """One row per live key: the graph's keys, plus keys that only the measurement saw."""
    topics = live_topics(node)
    if measurement is not None:
        for key in measurement.traffic.keys():  # noqa: SIM118 - Traffic is not a dict: keys() is its own method
            name = topic_name(key, node.namespace, node.graph)
            if name not in topics:
                typename = schema_type(measurement.encodings.get(key, "")) or "?"
                topics[name] = Topic(name, node.graph.name_of(key) or key, typename, (), key)
    silent = [
        t.data_key
        for t in topics.values()
        if "pub" in t.kinds and (measurement is None or not measurement.figures(t.data_key).count)
    ]
    held = latched(node.session, silent)
    rows: list[tuple[str, ...]] = []
    for name in sorted(topics):
        topic = topics[name]
        rate = bandwidth = NOTHING
        if topic.data_key in held:
            rate = "latched"
        elif measurement is not None and "srv" not in topic.kinds:
            figures = measurement.figures(topic.data_key)
            rate = format_rate(figures)
            bandwidth = format_bandwidth(figures.bytes_per_s) if figures.count else NOTHING
        rows.append((name, topic.typename, " ".join(topic.kinds) or NOTHING, rate, bandwidth))
    return rows


def format_table(rows: Sequence[tuple[str, ...]]) -> str:
    """Left-aligned columns, two spaces apart (no cell holds two spaces, so the table splits back)."""
    widths = [max(len(row[i]) for row in (COLUMNS, *rows)) for i in range(len(COLUMNS))]
    return "\n".join(
        "  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip() for row in (COLUMNS, *rows)
    )


def run(node: Node, stop: threading.Event, window_s: float) -> int:
    """Prints the table of live keys, their rates measured over `window_s` (0: the graph only); the exit code."""
    measurement = measure(node, window_s, stop) if window_s > 0 else None
    if stop.is_set():
        return 0
    rows = table_rows(node, measurement)
    if not rows:
        where = f"in namespace {node.namespace!r}" if node.namespace else "without a namespace"
        raise ClientError(f"no live keys {where}: is the server running, with the same --namespace?")
    print(format_table(rows), flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot topics [--window S]`."""
    parser = client_parser("simbot topics", "List the live keys with their type, who uses them, rate and bandwidth.")
    parser.add_argument(
        "--window",
        type=number(float, at_least_zero=True),
        default=DEFAULT_WINDOW_S,
        metavar="SECONDS",
        help=f"how long to measure rates and bandwidth (default {DEFAULT_WINDOW_S:g}); 0 lists the graph only, "
        "without subscribing (measuring subscribes to the cameras too, so the server renders meanwhile)",
    )
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, args.window))


if __name__ == "__main__":
    sys.exit(main())
