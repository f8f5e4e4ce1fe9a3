"""What every client program does the same way: its command line, its bus session, its stop.

A client parses its options (the bus options of every simbot program, plus its own), opens a
Zenoh *client* session (connecting to the server, listening on nothing), and runs its body until
the body returns or SIGINT / SIGTERM sets `stop`. A user's mistake (a bad option, a bad Zenoh
config, no server to connect to) is one line on stderr and exit code 2, never a traceback.

Zenoh calls subscription callbacks on its own threads; clients hand messages to their main loop
through a `Mailbox` and do their work there.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import threading
from collections import deque
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, add_bus_arguments

EXIT_USAGE = 2
T = TypeVar("T")
Number = TypeVar("Number", int, float)

ClientBody = Callable[[argparse.Namespace, Node, threading.Event], int]
"""The client's work: (its options, its bus node, the stop event) → exit code."""


class ClientError(Exception):
    """A user's mistake found after parsing (a key that does not exist, a file that cannot be written)."""


def client_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A parser with `-v` and the bus options; the client adds its own arguments."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    add_bus_arguments(parser)
    return parser


def number(kind: Callable[[str], Number], *, at_least_zero: bool = False) -> Callable[[str], Number]:
    """An argparse type: a finite number > 0 (≥ 0 with `at_least_zero`); argparse's one-line error otherwise."""
    bound = "≥ 0" if at_least_zero else "> 0"

    def parse(text: str) -> Number:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not math.isfinite(value) or value < 0 or (value == 0 and not at_least_zero):
            raise argparse.ArgumentTypeError(f"expected a finite number {bound}, got {text!r}")
        return value

    return parse


def run_client(parser: argparse.ArgumentParser, argv: Sequence[str] | None, body: ClientBody) -> int:
    """Parse, open the bus, run `body` until it returns or a signal asks to stop; the exit code."""
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
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
