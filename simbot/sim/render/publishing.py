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

A product's CDR is written in place (`simbot.bus.in_place.InPlace`, through the bus's encoder
registry): one copy of the pixels from shared memory into the first frame's encoding, where
building a message and encoding it took three.

In lockstep the worker asks the server's barrier queryable (`Bus.barrier`, `Node.answering`)
after its puts and before it reports the frame done: the query follows the samples on the one link
to the server, so its reply means they are routed, ahead of the clock the server publishes after
the frame, as they were when the server put them itself.
"""

from __future__ import annotations

import logging
from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace
from typing import Any

from simbot.bus import BusOptions, Node, messages
from simbot.bus.in_place import Build, InPlace
from simbot.bus.node import Publisher
from simbot.sim.render.kinds import Array

log = logging.getLogger(__name__)

BARRIER_TIMEOUT_S = 10.0
MATCH_TIMEOUT_S = 5.0
"""How long a lockstep worker waits for its session to hear of a subscriber the server counted (it
takes under a millisecond; a subscriber that left meanwhile costs this once)."""


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
