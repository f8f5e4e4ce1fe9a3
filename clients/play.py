"""`simbot play BAG [--rate R]`: a recorded bag published back onto the bus, like `ros2 bag play`.

Each topic `/<name>` of the bag goes out on the key `<name>` in the player's namespace, with the
type the bag records (the sample encoding names it, the graph announces it), as the unchanged
bytes of the recording: the messages keep their sim-time header stamps and `/clock` is played like
any topic, so subscribers see the recorded sim time. Messages go out in the bag's time order, each
when its recorded arrival time comes round again (divided by `--rate`). Topics recorded with
transient-local durability are latched again. Publishers block rather than drop, so nothing of
the recording is lost on a busy link.

It starts once every topic has a subscriber (at most `ROUTES_S` later), so none of the first
messages goes out before its route exists.

Play on a bus without a server (or in another namespace): two publishers of `/odom` confuse every
subscriber, as in ROS.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

from rosbags.interfaces import Connection, ConnectionExtRosbag2, QosDurability
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError

from simbot.arguments import number
from simbot.bus import Node
from simbot.bus.node import Publisher

from .common import ClientError, client_parser, run_client

logger = logging.getLogger(__name__)

ROUTES_S = 2.0
"""The longest play waits, after declaring its publishers, for subscribers' routes to them: it starts as soon as
every key has a subscriber, and after this when some key has none (a fixed pause lost the first messages under load)."""


def transient_local(connection: Connection) -> bool:
    """Whether the topic was recorded latched (any offered profile is transient-local)."""
    ext = connection.ext
    return isinstance(ext, ConnectionExtRosbag2) and any(
        qos.durability == QosDurability.TRANSIENT_LOCAL for qos in ext.offered_qos_profiles
    )


def open_bag(path: Path) -> Reader:
    """The bag opened for reading, or a ClientError naming it."""
    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError) as exc:
        raise ClientError(f"{path}: cannot open the bag: {exc}") from None
    return reader


def publishers(node: Node, reader: Reader) -> dict[int, Publisher]:
    """A publisher per connection of the bag, by connection id; a topic name that is no valid key is a ClientError."""
    found = {}
    for connection in reader.connections:
        try:
            found[connection.id] = node.publisher(
                connection.topic, connection.msgtype, latched=transient_local(connection), drop=False
            )
        except ValueError as exc:
            raise ClientError(f"{reader.path}: {exc}") from None
    return found


def await_routes(outputs: dict[int, Publisher], stop: threading.Event) -> None:
    """Until every publisher has a subscriber, at most ROUTES_S: a message put before its route exists goes nowhere."""
    deadline = time.monotonic() + ROUTES_S
    while not all(p.has_subscribers for p in outputs.values()) and time.monotonic() < deadline:
        if stop.wait(0.01):
            return


def timed(reader: Reader, rate: float, stop: threading.Event) -> Iterator[tuple[Connection, bytes]]:
    """The bag's messages in time order, each given out when its time (scaled by 1/rate) comes; ends early on `stop`."""
    start_wall = time.monotonic()
    start_bag: int | None = None
    for connection, timestamp, data in reader.messages():
        start_bag = timestamp if start_bag is None else start_bag
        due = start_wall + (timestamp - start_bag) / 1e9 / rate
        if stop.wait(max(0.0, due - time.monotonic())):
            return
        yield connection, data


def run(node: Node, stop: threading.Event, bag: str, rate: float) -> int:
    """Publishes the messages of `bag` (a directory or its file) at `rate` × their recorded pace until done or `stop`."""
    reader = open_bag(Path(bag))
    total = reader.message_count
    try:
        outputs = publishers(node, reader)
        await_routes(outputs, stop)
        played = 0
        for connection, data in timed(reader, rate, stop):
            outputs[connection.id].put_raw(data)
            played += 1
    finally:
        reader.close()
    print(f"played {played} of {total} messages from {bag}", file=sys.stderr)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot play BAG [--rate R]`."""
    parser = client_parser("simbot play", "Publish a recorded rosbag2 bag back onto the bus at its recorded rate.")
    parser.add_argument("bag", help="bag directory (or its .mcap / .db3 file)")
    parser.add_argument(
        "--rate", type=number(float), default=1.0, help="speed factor: 2 plays twice as fast (default 1)"
    )
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, args.bag, args.rate))


if __name__ == "__main__":
    sys.exit(main())
