"""`simbot record [-o BAG] [KEYS…]`: the bus into a rosbag2 bag in MCAP storage, like `ros2 bag record`.

Every chosen key (all published keys when none is named; names may be globs such as
`camera_*/image`) is written with its ROS 2 type and message definition, under the ROS topic
name `/<key>` without the namespace, so `ros2 bag play`, Foxglove and rosbags read the bag. Keys
that appear on the graph later are picked up (the graph is looked at every second). A latched
key (`tf_static`, `robot_description`) is recorded with transient-local durability, so a player
latches it again.

Each message is stamped with its arrival time (wall clock), as rosbag2 does; the messages keep
their sim-time header stamps. The payloads go into the bag unchanged; malformed ones are dropped
and counted by the tap (`clients/tap.py`). Zenoh threads only queue samples (the queue is not
bounded: nothing already received is let go); the loop writes them. Ctrl-C, SIGTERM or
`--duration` end the recording: the queue is written out, then the bag is closed, so the file
opens and holds everything received.

When sim time goes back (the server restarted, or the world was reset) the recording goes on:
the bag's timestamps, on the wall clock, still only go forward (rosbags' writer would take them
in any order, but a player replays them in order), while the header stamps start again from zero.
The jump is logged, and listed in the bag's metadata.yaml under `custom_data`
(`simbot.sim_time_went_back`: a JSON list of `{"time_ns": …, "from_ns": …, "to_ns": …}`, the bag
time at which the new run's first clock arrived and the sim times before and after), so that a
reader can tell the runs apart.
"""

from __future__ import annotations

import fnmatch
import json
import logging
import queue
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.rosbag2.errors import WriterError

from simbot.arguments import number
from simbot.bus import Node
from simbot.bus.codec import TYPESTORE

from .common import ClientError, ClockSubscriber, TimeJump, client_parser, run_client
from .tap import RawSample, Tap, published
from .topics import Topic, latched

logger = logging.getLogger(__name__)

BAG_VERSION: Literal[8, 9] = 8
"""rosbags writes metadata version 8 or 9. Version 9 (Jazzy's) writes each topic's QoS as a YAML list,
which Humble's parser refuses; version 8 keeps the string form that Humble and later read."""
GRAPH_PERIOD_S = 1.0
PROGRESS_PERIOD_S = 0.5
PLAIN_PROGRESS_PERIOD_S = 5.0
"""Without a terminal (a log file, a container), a progress line every few seconds instead of a redrawn one."""
WAIT_WARNING_S = 5.0
NO_TIME = QosTime(0, 0)
JUMPS_KEY = "simbot.sim_time_went_back"
"""The custom_data key in metadata.yaml that lists the times sim time went back."""


def offered_qos(transient_local: bool) -> Qos:
    """The QoS a topic is recorded with: reliable, keep-last 1, transient-local for latched keys."""
    durability = QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE
    return Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        durability,
        NO_TIME,
        NO_TIME,
        QosLiveliness.AUTOMATIC,
        NO_TIME,
        False,
    )


def ros_topic(name: str) -> str:
    """The ROS topic name a key is recorded under: `/` and the key without the namespace."""
    return "/" + name.strip("/")


def default_bag_name() -> str:
    """`rosbag2_YYYY_MM_DD-HH_MM_SS`, the name `ros2 bag record` picks."""
    return time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


class Selection:
    """Which published topics to record: the named ones (globs allowed), or all; minus the excluded."""

    def __init__(self, names: Sequence[str], exclude: Sequence[str]) -> None:
        self.names = [name.strip("/") for name in names]
        self.exclude = [pattern.strip("/") for pattern in exclude]

    def chosen(self, name: str) -> bool:
        """Whether the topic `name` is recorded."""
        if any(fnmatch.fnmatchcase(name, pattern) for pattern in self.exclude):
            return False
        return not self.names or any(fnmatch.fnmatchcase(name, pattern) for pattern in self.names)

    def missing(self, seen: Sequence[str]) -> list[str]:
        """The named topics (or patterns) that match nothing seen yet."""
        return [pattern for pattern in self.names if not any(fnmatch.fnmatchcase(name, pattern) for name in seen)]


class Bag:
    """The rosbag2 being written: one connection per topic, counts and bytes for the progress line."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self.writer = Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
            self.writer.open()
        except WriterError as exc:
            raise ClientError(f"-o {path}: {exc}") from None
        except OSError as exc:
            raise ClientError(f"-o {path}: cannot create the bag: {exc.strerror or exc}") from None
        self.connections: dict[str, Connection] = {}
        self.jumps: list[dict[str, int]] = []
        self.messages = 0
        self.bytes = 0
        self.started = time.monotonic()

    def add(self, topic: Topic, transient_local: bool) -> None:
        """A connection for `topic` with its type, message definition and QoS."""
        self.connections[topic.name] = self.writer.add_connection(
            ros_topic(topic.name),
            topic.typename,
            typestore=TYPESTORE,
            offered_qos_profiles=[offered_qos(transient_local)],
        )

    def write(self, sample: RawSample) -> None:
        """One message, stamped with its arrival time."""
        self.writer.write(self.connections[sample.topic], sample.received_ns, sample.data)
        self.messages += 1
        self.bytes += len(sample.data)

    def mark(self, jump: TimeJump) -> None:
        """Note in the metadata that sim time went back, at the bag time the new run's first clock arrived."""
        self.jumps.append({"time_ns": jump.wall_ns, "from_ns": jump.from_ns, "to_ns": jump.to_ns})
        self.writer.set_custom_data(JUMPS_KEY, json.dumps(self.jumps))

    def progress(self) -> str:
        """Messages, megabytes and seconds so far."""
        return f"{self.messages} messages, {self.bytes / 1e6:.1f} MB, {time.monotonic() - self.started:.1f} s"

    def close(self) -> None:
        """Finish the MCAP file and write metadata.yaml."""
        self.writer.close()


class Recorder:
    """The loop: watch the graph, tap chosen topics, write what the tap queued, show progress."""

    def __init__(self, node: Node, bag: Bag, selection: Selection) -> None:
        self.node = node
        self.bag = bag
        self.selection = selection
        self.queue: queue.SimpleQueue[RawSample | TimeJump] = queue.SimpleQueue()
        self.tap = Tap(node, self.queue.put)
        self.clock = ClockSubscriber(node, on_jump=self.queue.put)  # recorded or not, the clock says when a run began
        self.live = sys.stderr.isatty()
        self._next_graph = 0.0
        self._next_progress = time.monotonic() + PROGRESS_PERIOD_S
        self._warned_missing = False

    def watch_graph(self, now: float) -> None:
        """Tap the chosen topics the graph lists that are not tapped yet (connection first, then subscription)."""
        if now < self._next_graph:
            return
        self._next_graph = now + GRAPH_PERIOD_S
        topics = published(self.node)
        new = [
            topic for name, topic in topics.items() if self.selection.chosen(name) and name not in self.bag.connections
        ]
        latched_keys = latched(self.node.session, [topic.data_key for topic in new]) if new else set()
        for topic in new:
            self.bag.add(topic, topic.data_key in latched_keys)
            self.tap.listen(topic)
            logger.info(
                "recording %s (%s%s)",
                ros_topic(topic.name),
                topic.typename,
                ", latched" if topic.data_key in latched_keys else "",
            )
        self._warn_missing(now, list(topics))

    def _warn_missing(self, now: float, seen: list[str]) -> None:
        missing = self.selection.missing(seen)
        if missing and not self._warned_missing and now - self.bag.started > WAIT_WARNING_S:
            self._warned_missing = True
            logger.warning("still waiting for %s: nothing publishes it yet", ", ".join(missing))

    def write_queued(self, timeout: float) -> None:
        """Write what the tap queued, waiting up to `timeout` for the first sample."""
        try:
            item = self.queue.get(timeout=timeout)
        except queue.Empty:
            return
        self._take(item)
        self.drain()

    def drain(self) -> None:
        """Write everything queued, without waiting."""
        while True:
            try:
                self._take(self.queue.get_nowait())
            except queue.Empty:
                return

    def _take(self, item: RawSample | TimeJump) -> None:
        if isinstance(item, TimeJump):
            self.bag.mark(item)
        else:
            self.bag.write(item)

    def show_progress(self, now: float) -> None:
        """The progress line: redrawn on a terminal, a line every few seconds otherwise."""
        if now < self._next_progress:
            return
        self._next_progress = now + (PROGRESS_PERIOD_S if self.live else PLAIN_PROGRESS_PERIOD_S)
        line = f"recording {len(self.bag.connections)} topics: {self.bag.progress()}"
        print(f"\r\x1b[2K{line}" if self.live else line, end="" if self.live else "\n", file=sys.stderr, flush=True)

    def run(self, stop: threading.Event, duration: float | None) -> None:
        """Record until stopped or `duration` seconds have passed."""
        end = None if duration is None else self.bag.started + duration
        while not stop.is_set():
            now = time.monotonic()
            if end is not None and now >= end:
                break
            self.watch_graph(now)
            self.write_queued(timeout=0.1)
            self.show_progress(now)

    def finish(self) -> None:
        """Stop tapping, write what is still queued, close the bag, say what it holds."""
        self.tap.close()
        self.drain()
        self.bag.close()
        if self.live:
            print(file=sys.stderr)
        dropped = sum(self.tap.dropped.values())
        note = f"; dropped {dropped} malformed samples" if dropped else ""
        if self.bag.jumps:
            note += f"; sim time went back {len(self.bag.jumps)} times (custom_data {JUMPS_KEY} in metadata.yaml)"
        print(
            f"wrote {self.bag.path}: {len(self.bag.connections)} topics, {self.bag.progress()}{note}", file=sys.stderr
        )


def run(node: Node, stop: threading.Event, output: Path, selection: Selection, duration_s: float | None) -> int:
    """Records the selected keys into the bag `output` for `duration_s` (None: until `stop`), then closes it."""
    recorder = Recorder(node, Bag(output), selection)
    try:
        recorder.run(stop, duration_s)
    finally:
        recorder.finish()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot record [-o BAG] [KEYS…] [--exclude GLOB] [--duration S]`."""
    parser = client_parser(
        "simbot record", "Record keys of the bus into a rosbag2 bag in MCAP storage; Ctrl-C closes it."
    )
    parser.add_argument(
        "keys",
        nargs="*",
        metavar="KEY",
        help="topic names or globs, e.g. scan 'camera_*/image' (default: every published key)",
    )
    parser.add_argument(
        "-o", "--output", metavar="BAG", help="bag directory to create (default: rosbag2_<date>-<time>)"
    )
    parser.add_argument(
        "--exclude", action="append", default=[], metavar="GLOB", help="leave out matching topic names, repeatable"
    )
    parser.add_argument(
        "--duration", type=number(float), metavar="SECONDS", help="stop after this many seconds (default: until Ctrl-C)"
    )
    return run_client(
        parser,
        argv,
        lambda args, node, stop: run(
            node, stop, Path(args.output or default_bag_name()), Selection(args.keys, args.exclude), args.duration
        ),
    )


if __name__ == "__main__":
    sys.exit(main())
