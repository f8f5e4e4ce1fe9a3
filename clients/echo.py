"""`simbot echo KEY`: the decoded messages of one key, like `ros2 topic echo`.

The type comes from each sample's encoding (`application/cdr;<type>`, which simbot's publishers
set), else from the graph. Messages print as nested `field: value` lines separated by `---`, or
with `--json` as one JSON object per line. Numeric arrays longer than 16 elements and strings
longer than 256 characters are summarised (length, dtype, min/max of the finite values, how many
are inf or NaN; the head of the string) unless `--full`. JSON has no infinities or NaN, so they
are written as the strings "inf", "-inf" and "nan" (null would confuse a lidar's "no return",
+inf, with "no measurement", NaN).

The subscriber is a Zenoh advanced subscriber asking for history, so a late joiner gets the last
message of a latched key (`robot_description`, `tf_static`, `detachable_joint/state`); on a
plain publisher it is an ordinary subscriber. Subscribing to a camera makes the server render it;
the first image of a camera nobody watched may take a few seconds (the render workers start).
A key that is neither on the graph nor sending within `--wait` seconds is a mistake: one line
naming it (and similar live keys), exit 2.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import zenoh

from simbot.arguments import number
from simbot.bus import DecodeError, Node, UnknownMessageType, decode

from .common import ClientError, Mailbox, client_parser, run_client
from .topics import Topic, live_topics, schema_type

logger = logging.getLogger(__name__)

ARRAY_LIMIT = 16
STRING_LIMIT = 256
DEFAULT_WAIT_S = 5.0
GRAPH_POLL_S = 0.25
QUEUE = 256
"""Samples waiting to be printed; at 200 Hz, a second of slow terminal."""
SEPARATOR = "---"
YAML_PLAIN = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_./-+()")


# --- a message as plain data ----------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Summary:
    """A long numeric array in brief: what `ros2 topic echo` would scroll past."""

    length: int
    dtype: str
    min: float | int | None
    max: float | int | None
    inf: int | None = None
    nan: int | None = None


def _number(value: np.generic) -> float | int | bool:
    """A numpy scalar as Python's, float32 by its shortest decimal (0.532, not 0.5320000052452087)."""
    return float(str(value)) if isinstance(value, np.floating) else value.item()


def summarise(array: npt.NDArray[Any]) -> Summary:
    """Length, dtype, min and max of the finite values, and (for floats) how many are ±inf and NaN."""
    if not np.issubdtype(array.dtype, np.floating):
        low, high = (_number(array.min()), _number(array.max())) if array.size else (None, None)
        return Summary(int(array.size), str(array.dtype), low, high)
    finite = array[np.isfinite(array)]
    low, high = (_number(finite.min()), _number(finite.max())) if finite.size else (None, None)
    return Summary(int(array.size), str(array.dtype), low, high, int(np.isinf(array).sum()), int(np.isnan(array).sum()))


def to_plain(value: Any, full: bool = False) -> Any:
    """A decoded message as dicts, lists, numbers and strings; long arrays and strings summarised unless `full`."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: to_plain(getattr(value, f.name), full)
            for f in dataclasses.fields(value)
            if not f.name.startswith("__")
        }
    if isinstance(value, np.ndarray):
        if full or value.size <= ARRAY_LIMIT:
            return [_number(v) for v in value.reshape(-1)]
        return summarise(value)
    if isinstance(value, (list, tuple)):
        return [to_plain(item, full) for item in value]
    if isinstance(value, str) and not full and len(value) > STRING_LIMIT:
        return f"{value[:STRING_LIMIT]}... ({len(value)} characters; --full prints all)"
    if isinstance(value, np.generic):
        return _number(value)
    return value


# --- YAML-like and JSON text ----------------------------------------------------------------


def _float_text(value: float) -> str:
    return repr(value) if math.isfinite(value) else ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))


def _scalar(value: Any) -> str:
    """One value on one line, as `ros2 topic echo` writes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return _float_text(value)
    if isinstance(value, str):
        return value if value and set(value) <= YAML_PLAIN else json.dumps(value, ensure_ascii=False)
    if isinstance(value, Summary):
        extremes = (
            f"min {_scalar(value.min)}, max {_scalar(value.max)}" if value.min is not None else "no finite values"
        )
        counts = f", {value.inf} inf, {value.nan} nan" if value.inf is not None else ""
        return f"<{value.length} × {value.dtype}: {extremes}{counts}>"
    if isinstance(value, list):
        return "[" + ", ".join(_scalar(item) for item in value) + "]"
    if isinstance(value, dict) and not value:
        return "{}"
    return str(value)


def yaml_lines(fields: Mapping[str, Any], indent: int = 0) -> Iterator[str]:
    """Nested `name: value` lines; sequences of messages as `- ` items (ROS 2's echo layout)."""
    pad = " " * indent
    for name, value in fields.items():
        if isinstance(value, dict) and value:
            yield f"{pad}{name}:"
            yield from yaml_lines(value, indent + 2)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            yield f"{pad}{name}:"
            for item in value:
                lines = list(yaml_lines(item, indent + 2)) or [f"{pad}  {{}}"]
                yield f"{pad}- {lines[0][indent + 2 :]}"
                yield from lines[1:]
        else:
            yield f"{pad}{name}: {_scalar(value)}"


def jsonable(value: Any) -> Any:
    """Plain data that `json.dumps(allow_nan=False)` takes: summaries as objects, inf and NaN as strings."""
    if isinstance(value, Summary):
        return {k: v for k, v in dataclasses.asdict(value).items() if v is not None or k in ("min", "max")}
    if isinstance(value, float) and not math.isfinite(value):
        return _float_text(value)
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [jsonable(v) for v in value]
    return value


def render(msg: Any, as_json: bool, full: bool) -> str:
    """The text of one message: a JSON line, or YAML-like lines followed by `---`."""
    plain = to_plain(msg, full)
    if as_json:
        return json.dumps(jsonable(plain), allow_nan=False, ensure_ascii=False)
    return "\n".join([*yaml_lines(plain), SEPARATOR])


# --- the client -----------------------------------------------------------------------------


def similar(name: str, names: Sequence[str]) -> list[str]:
    """Live topic names a user may have meant: close spellings and those containing `name`."""
    close = difflib.get_close_matches(name, names, n=5, cutoff=0.6)
    return close + [n for n in names if name and name in n and n not in close][: 5 - len(close)]


def _unknown(name: str, wait_s: float, topics: Mapping[str, Topic]) -> ClientError:
    hint = similar(name, sorted(topics))
    suffix = f"; similar: {', '.join(hint)}" if hint else ""
    return ClientError(f"key {name!r}: nothing publishes or subscribes to it (waited {wait_s:g} s){suffix}")


@dataclass(frozen=True)
class Echoed:
    """What `simbot echo` prints: the key (its topic name), how, and how long it waits for it."""

    key: str
    once: bool = False
    """Stop after the first message."""
    as_json: bool = False
    full: bool = False
    """Long arrays and strings whole."""
    wait_s: float = DEFAULT_WAIT_S
    """How long the key may be absent from the bus before it is an error."""


class Echo:
    """One key's samples, queued by Zenoh, typed, decoded and printed by the loop."""

    def __init__(self, node: Node, echoed: Echoed) -> None:
        self.node = node
        self.echoed = echoed
        try:
            self.key = node.graph.any_type_key(node.key(echoed.key))
        except ValueError as exc:
            raise ClientError(str(exc)) from None
        self.name = echoed.key.strip("/")
        self.topic: Topic | None = None
        self.inbox: Mailbox[tuple[bytes, str]] = Mailbox(QUEUE)

    def on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh thread: queue the payload and its encoding."""
        if sample.kind == zenoh.SampleKind.PUT:
            self.inbox.put((sample.payload.to_bytes(), str(sample.encoding)))

    def look_up(self) -> bool:
        """Whether the graph knows the key as a topic; a service is a mistake."""
        topics = live_topics(self.node)
        topic = topics.get(self.name)
        if topic is not None and topic.kinds == ("srv",):
            raise ClientError(f"key {self.name!r} is a JSON service (world control), not a topic; echo prints topics")
        self.topic = topic or self.topic
        return self.topic is not None

    def typename(self, encoding: str) -> str:
        """The sample's own type, else the graph's."""
        typename = schema_type(encoding)
        if typename is None:
            if self.topic is None:
                self.look_up()
            typename = self.topic.typename if self.topic is not None else None
        if typename is None:
            raise ClientError(f"key {self.name!r}: its samples name no ROS 2 type and the graph announces none")
        return typename

    def show(self, payload: bytes, encoding: str) -> bool:
        """Prints one sample; False when it could not be decoded (logged)."""
        typename = self.typename(encoding)
        try:
            msg = decode(payload, typename)
        except (DecodeError, UnknownMessageType) as exc:
            logger.warning("%s: skipped a sample: %s", self.name, exc)
            return False
        print(render(msg, self.echoed.as_json, self.echoed.full), flush=True)
        return True

    def run(self, stop: threading.Event) -> int:
        """Prints until stopped (or after one message with --once); waits `--wait` s for an unknown key."""
        deadline = time.monotonic() + self.echoed.wait_s
        known = False
        while not stop.is_set():
            item = self.inbox.get(GRAPH_POLL_S)  # a quiet poll period between two looks at the graph
            if item is not None:
                known = True
                if self.show(*item) and self.echoed.once:
                    return 0
            elif not known:
                known = self.look_up()
                if not known and time.monotonic() > deadline:
                    raise _unknown(self.name, self.echoed.wait_s, live_topics(self.node))
        return 0


def run(node: Node, stop: threading.Event, echoed: Echoed) -> int:
    """Prints the messages of `echoed`'s key until `stop` (or the first, `once`); the exit code."""
    echo = Echo(node, echoed)
    history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1)
    subscriber = zenoh.ext.declare_advanced_subscriber(node.session, echo.key, echo.on_sample, history=history)
    try:
        return echo.run(stop)
    except BrokenPipeError:  # `simbot echo imu_scan | head`: the reader is gone, which is no error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        subscriber.undeclare()


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot echo KEY [--once] [--json] [--full] [--wait S]`."""
    parser = client_parser("simbot echo", "Print the decoded messages of a key, like `ros2 topic echo`.")
    parser.add_argument("key", help="topic name, e.g. odom or camera_front/camera_info (the namespace is applied)")
    parser.add_argument("--once", action="store_true", help="exit after the first message")
    parser.add_argument("--json", action="store_true", help="one JSON object per line (inf and NaN as strings)")
    parser.add_argument(
        "--full",
        action="store_true",
        help=f"print arrays over {ARRAY_LIMIT} elements and strings over {STRING_LIMIT} characters whole",
    )
    parser.add_argument(
        "--wait",
        type=number(float, at_least_zero=True),
        default=DEFAULT_WAIT_S,
        metavar="SECONDS",
        help=f"how long a key may be absent from the bus before it is an error (default {DEFAULT_WAIT_S:g})",
    )
    return run_client(
        parser,
        argv,
        lambda args, node, stop: run(node, stop, Echoed(args.key, args.once, args.json, args.full, args.wait)),
    )


if __name__ == "__main__":
    sys.exit(main())
