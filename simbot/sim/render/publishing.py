"""Images leave from where they are drawn: a render worker puts its cameras' messages on the bus
itself, so the physics process never carries a pixel.

The server says, per camera, what goes out (`Publication`, plain data that crosses the process
boundary): each product's key, the output it shows and the function that makes its message from
the output's array (a module-level function, pickled by name), the frame id its messages carry (a
robot's namespace already in it), and camera_info's key and message. A worker joins the bus as a
client of the server (`Bus`, `simbot.bus.options.helper_options`) and declares a plain publisher
per key, unannounced: the server's own publishers announce the keys on the graph and say whether
anyone watches, which decides whether a frame is drawn at all. After a frame is drawn and
finished, the products the server found subscribed when it asked for the frame (the request's
`publish`) go out, then camera_info, under the frame's stamp (image_transport's CameraSubscriber
and exact-time synchronisers pair them by it).

Whether a frame goes out is the server's decision alone, never the worker's session's view: that
session learns of a subscriber some time after the server does (its publishers' matching status
is false for a while after they are declared, longer on a loaded machine), and a worker that
asked its own session once dropped the first frames of a seeded lockstep run now and then (issue
46). In lockstep a worker whose session has not yet heard of a subscriber the server counts waits
for it (`Publisher.await_subscribers`, up to `MATCH_TIMEOUT_S`), so that Zenoh's own filtering on
the publisher's side cannot drop the put either; in real time it puts at once.

A product's CDR is written in place (`InPlace`): the first frame's message is built and encoded,
and where its stamp and its array's bytes lie in the encoding is found by encoding it again with
other ones; each later frame copies that encoding, writes its stamp there and copies the array's
bytes from shared memory into it, one copy of the pixels where building a message and encoding it
took three. A builder whose bytes are not its array's (none of simbot's) is checked once and built
each frame.

In lockstep the worker asks the server's barrier queryable (`Bus.barrier`, `Node.answering`)
after its puts and before it reports the frame done: the query follows the samples on the one link
to the server, so its reply means they are routed, ahead of the clock the server publishes after
the frame, as they were when the server put them itself.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from simbot.bus import BusOptions, Node, messages
from simbot.bus.codec import encode
from simbot.bus.node import Publisher
from simbot.sim.render.kinds import Array

log = logging.getLogger(__name__)

Build = Callable[[int, str, Any], Any]
"""(stamp ns, frame id, the output's array) → the message."""
BARRIER_TIMEOUT_S = 10.0
MATCH_TIMEOUT_S = 5.0
"""How long a lockstep worker waits for its session to hear of a subscriber the server counted (it
takes under a millisecond; a subscriber that left meanwhile costs this once)."""
STAMP = slice(4, 12)
"""builtin_interfaces/Time (int32 s, uint32 ns) right after the 4-byte CDR encapsulation: where
every message that starts with a std_msgs/Header keeps its stamp."""


@dataclass(frozen=True)
class Bus:
    """How a worker reaches the bus."""

    options: BusOptions
    """A client of the server (`helper_options`)."""
    barrier: str | None = None
    """The server's barrier queryable, its key in full (lockstep); None: the worker never waits for its samples."""


@dataclass(frozen=True)
class Route:
    """One product: the output it shows, on which key, made by which function."""

    key: str
    """The full Zenoh key, namespace and all."""
    typename: str
    output: str
    build: Build


@dataclass(frozen=True)
class Publication:
    """What a worker publishes for one camera."""

    frame_id: str
    """As the messages carry it (a robot's namespace applied)."""
    routes: tuple[Route, ...]
    info_key: str
    info: Any
    """sensor_msgs/CameraInfo, its header's frame id set; stamped per frame."""


class InPlace:
    """One product's CDR, written in place per frame; see the module docstring."""

    def __init__(self, build: Build, frame_id: str) -> None:
        self.build = build
        self.frame_id = frame_id
        self._encoded: bytes | None = None
        self._data: slice | None = None
        self._checked = False

    def encode(self, stamp_ns: int, array: Array) -> bytes | bytearray:
        if self._encoded is not None and self._data is not None:
            out = bytearray(self._encoded)
            out[STAMP] = stamp_bytes(stamp_ns)
            out[self._data] = np.ascontiguousarray(array).reshape(-1).view(np.uint8).data
            return out
        encoded = encode(self.build(stamp_ns, self.frame_id, array))
        if not self._checked:
            self._checked = True
            self._learn(encoded, stamp_ns, array)
        return encoded

    def _learn(self, encoded: bytes, stamp_ns: int, array: Array) -> None:
        """Where the stamp and the array's bytes lie, kept only where writing them there gives the
        very encoding the builder gives."""
        raw = np.ascontiguousarray(array).reshape(-1).view(np.uint8)
        flipped = (~raw).view(array.dtype).reshape(array.shape)
        other = encode(self.build(stamp_ns, self.frame_id, flipped))
        differ = np.flatnonzero(np.frombuffer(encoded, np.uint8) != np.frombuffer(other, np.uint8))
        if (
            len(other) != len(encoded)
            or len(differ) != raw.size
            or (raw.size and differ[-1] - differ[0] + 1 != raw.size)
        ):
            log.debug("%s: its message's bytes are not its array's; built each frame", self.build.__name__)
            return
        start = int(differ[0]) if raw.size else len(encoded)
        self._encoded, self._data = encoded, slice(start, start + raw.size)
        if bytes(self.encode(stamp_ns + 1, array)) != encode(self.build(stamp_ns + 1, self.frame_id, array)):
            log.debug("%s: its stamp is not where a header keeps it; built each frame", self.build.__name__)
            self._encoded = self._data = None


def stamp_bytes(stamp_ns: int) -> bytes:
    stamp = messages.time_msg(stamp_ns)
    return struct.pack("<iI", stamp.sec, stamp.nanosec)


@dataclass
class _Outlet:
    route: Route
    publisher: Publisher
    writer: InPlace


@dataclass
class _Camera:
    outlets: list[_Outlet]
    info_key: str
    info: Publisher
    template: Any


class FramePublisher:
    """A worker's session on the bus and its cameras' publishers."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.node = Node(bus.options, "client")
        self._cameras: dict[int, _Camera] = {}

    def add(self, camera: int, publication: Publication) -> None:
        """Declares the camera's keys (unannounced: the server announces them)."""
        outlets = [
            _Outlet(route, self._publisher(route.key, route.typename), InPlace(route.build, publication.frame_id))
            for route in publication.routes
        ]
        info = self._publisher(publication.info_key, publication.info.__msgtype__)
        self._cameras[camera] = _Camera(outlets, publication.info_key, info, publication.info)

    def _publisher(self, key: str, typename: str) -> Publisher:
        """In lockstep a sample is never dropped (the step waits for it, as it waits for the frame);
        in real time one that the network cannot take is (a late frame is worth nothing)."""
        drop = self.bus.barrier is None
        return self.node.publisher(key, typename, drop=drop, announced=False)

    def publish(self, camera: int, stamp_ns: int, arrays: Mapping[str, Array], keys: Collection[str]) -> None:
        """The camera's products on `keys` (those the server found subscribed), then its camera_info
        if its key is among them, under `stamp_ns`; in lockstep, back once the server has routed them."""
        held = self._cameras.get(camera)
        if held is None:
            return
        for outlet in held.outlets:
            if outlet.route.key in keys:
                self._ready(outlet.publisher).put_raw(outlet.writer.encode(stamp_ns, arrays[outlet.route.output]))
        if held.info_key in keys:
            info = replace(held.template, header=messages.header(stamp_ns, held.template.header.frame_id))
            self._ready(held.info).put(info)
        if self.bus.barrier is not None:
            self.node.call(self.bus.barrier, {}, timeout=BARRIER_TIMEOUT_S)

    def _ready(self, publisher: Publisher) -> Publisher:
        """In lockstep, once this session knows of a subscriber (see the module docstring)."""
        if self.bus.barrier is not None and not publisher.await_subscribers(MATCH_TIMEOUT_S):
            log.warning("%s: no subscriber heard of within %g s; put anyway", publisher.key, MATCH_TIMEOUT_S)
        return publisher

    def close(self) -> None:
        self.node.close()
