"""`simbot foxglove`: the live bus in the Foxglove app, over Foxglove's WebSocket protocol.

What foxglove_bridge does for a ROS 2 graph, for the simbot bus, on Foxglove's own server
(foxglove-sdk, the `foxglove` extra):

- Every key someone publishes in the namespace is a channel named like its ROS topic (`/scan`,
  `/camera_front/camera_info`: the names `simbot record` writes into bags). It carries the bus's
  CDR bytes unchanged (message encoding `cdr`); its schema is the ROS 2 type (`ros2msg`), named
  `sensor_msgs/msg/LaserScan` and holding the `.msg` definition with its dependencies, as
  rosbag2's MCAP files and foxglove_bridge give it, so the app decodes it like theirs.
- Both names of the protocol are served: `foxglove.sdk.v1` (current Foxglove apps) and
  `foxglove.websocket.v1` (Lichtblick, `@foxglove/ws-protocol`), which foxglove-sdk refuses: the
  SDK listens on a private loopback port behind a front that renames the subprotocol in the
  handshake (`subprotocols.py`).
- The graph is read about once a second: a key that appears gets a channel, one that goes has its
  channel closed.
- A key is subscribed on the bus (through `clients.tap`, which drops malformed payloads and counts
  them) only while some Foxglove client subscribes to its channel: the server renders a camera only
  while someone subscribes, so an idle viewer costs the simulation nothing. A client that joins a
  key already watched makes the tap subscribe afresh, so that the latched keys (`tf_static`,
  `robot_description`) reach it as they reached the first.
- Time is sim time, as foxglove_bridge gives it with `use_sim_time`: the server advertises the
  Time capability and broadcasts every `clock` (tapped always), and each message is logged at the
  latest sim time seen: the latest clock, or the message's own header stamp when that is later.
  Zenoh delivers the clock and the sensors on different threads, so a message can overtake the
  clock ticks of its own step (by 20-30 ms on a loaded machine); it is never logged before the sim
  time at which it was taken. Before the first clock that leaves its header stamp, and 0 for a
  message without one (ROS's "no time yet"); never wall time, which lies decades beyond sim time
  and would put the message off the app's timeline. When the clock goes back (a world reset, a
  server restart), the jump is logged once and the session is cleared, so that the app drops
  what it holds of the old timeline.
- The scene (`scene`, the world's markers) is tapped always, as the clock is: its mesh markers
  name the files (`file://` URIs) the app may fetch through the protocol's asset fetch (the Assets
  capability). Exactly those files are served, read when asked; any other URI is refused, so the
  bridge never serves an arbitrary file, and a mesh the scene names but that is missing is an
  error the app shows.
- A server that goes away takes its keys off the graph, so their channels close; when it (or
  another) comes back on the same endpoint, the bridge's bus session reconnects by itself and the
  channels open again, which the app subscribes to again by topic.

Foxglove's callbacks and Zenoh's only queue; the loop does the rest. The SDK is imported only
when the server starts, so `--help` works without it. Run it as `simbot foxglove` or
`python -m simbot.clients.foxglove` (as a path, `python clients/foxglove.py`, it would shadow the SDK).
"""

from __future__ import annotations

import logging
import queue
import sys
import threading
import time
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, cast
from urllib.parse import unquote, urlparse

from simbot.arguments import whole
from simbot.bus import Node, UnknownMessageType, decode, message_type
from simbot.bus.codec import TYPESTORE, DecodeError

from .common import ClientError, Mailbox, SimTimeWatch, client_parser, run_client
from .subprotocols import LOOPBACK, SubprotocolFront
from .tap import RawSample, Tap, published
from .topics import Topic

if TYPE_CHECKING:
    import foxglove
    from foxglove.websocket import ChannelView, Client, ServerListener, WebSocketServer

logger = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
NEEDS_EXTRA = "needs the foxglove extra: pip install 'simbot[foxglove]'"
CLOCK_TOPIC = "clock"
SCENE_TOPIC = "scene"
SCENE_TYPE = "visualization_msgs/msg/MarkerArray"
ALWAYS_TAPPED = frozenset({CLOCK_TOPIC, SCENE_TOPIC})
"""Keys the bridge reads whether anyone watches them: sim time, and the meshes it may serve."""
GRAPH_PERIOD_S = 1.0
WAIT_S = 0.05
INBOX_SIZE = 512
"""Samples queued for the loop; past that the oldest go (counted): a viewer wants the newest."""


class Change(NamedTuple):
    """A Foxglove client's subscription to a channel began (`subscribed`) or ended."""

    subscribed: bool
    client: int
    channel: int


class Listener:
    """Foxglove's ServerListener: subscriptions and their ends, queued for the loop (called on the SDK's threads)."""

    def __init__(self) -> None:
        self.changes: queue.SimpleQueue[Change] = queue.SimpleQueue()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.changes.put(Change(True, client.id, channel.id))

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        """Also called when the client goes, and when the channel is closed."""
        self.changes.put(Change(False, client.id, channel.id))


@cache
def schema_text(typename: str) -> str:
    """The `.msg` definition of a ROS 2 type followed by its dependencies, each after a line of `=` and
    `MSG: pkg/Type` (rosbag2's MCAP schemas, foxglove_bridge's `ros2msg` ones)."""
    return TYPESTORE.generate_msgdef(typename, ros_version=2)[0]


class SceneAssets:
    """The mesh files the latest scene names, served to the app by URI (the SDK calls `fetch` on its threads).

    The set is replaced whole (one assignment) from the loop, so a fetch sees one scene or the next."""

    def __init__(self) -> None:
        self._meshes: frozenset[str] = frozenset()

    def update(self, data: bytes) -> None:
        """Take the mesh URIs of a scene message (a malformed one changes nothing)."""
        try:
            scene = decode(data, SCENE_TYPE)
        except DecodeError as exc:
            logger.warning("/%s: %s", SCENE_TOPIC, exc)
            return
        self._meshes = frozenset(m.mesh_resource for m in scene.markers if m.mesh_resource)

    def fetch(self, uri: str) -> bytes | None:
        """The file a scene mesh URI names; None (refused) for any other URI, or a file that cannot be read."""
        if uri not in self._meshes:
            logger.warning("asset %s refused: not a mesh of the scene", uri)
            return None
        parsed = urlparse(uri)
        if parsed.scheme != "file":
            return None
        try:
            return Path(unquote(parsed.path)).read_bytes()
        except OSError as exc:
            logger.warning("asset %s: %s", uri, exc.strerror or exc)
            return None


class Bridge:
    """The channels of the live keys, the bus subscriptions their viewers need, and sim time.

    Everything here runs in the loop: the listener and the tap only queue.
    """

    def __init__(
        self, node: Node, server: WebSocketServer, context: foxglove.Context, listener: Listener, assets: SceneAssets
    ) -> None:
        self._node = node
        self._assets = assets
        self._server = server
        self._context = context
        self._changes = listener.changes
        self._inbox: Mailbox[RawSample] = Mailbox(size=INBOX_SIZE)
        self._tap = Tap(node, self._inbox.put)
        self._channels: dict[str, tuple[Topic, foxglove.Channel]] = {}
        self._names: dict[int, str] = {}
        self._watchers: dict[str, set[int]] = {}
        self._unknown_types: set[str] = set()
        self._sim_ns: int | None = None
        self._clock = SimTimeWatch()
        self.forwarded = 0

    # --- the graph ------------------------------------------------------------------------

    def refresh_graph(self) -> None:
        """Channels for the keys published now: new ones opened, gone ones (or ones that changed type) closed."""
        live = {name: topic for name, topic in published(self._node).items() if self._known(topic.typename)}
        gone = [name for name, (topic, _) in self._channels.items() if _identity(live.get(name)) != _identity(topic)]
        for name in gone:
            self._close(name)
        new = [topic for name, topic in sorted(live.items()) if name not in self._channels]
        for topic in new:
            self._open(topic)
        if gone or new:
            logger.info("%d channels (%s)", len(self._channels), _changes_text(new, gone))

    def _known(self, typename: str) -> bool:
        """Whether the typestore has the type (a schema to send); warns once per unknown type."""
        try:
            message_type(typename)
        except UnknownMessageType as exc:
            if typename not in self._unknown_types:
                self._unknown_types.add(typename)
                logger.warning("no channel for the keys of type %s: %s", typename, exc)
            return False
        return True

    def _open(self, topic: Topic) -> None:
        from foxglove import Channel, Schema

        schema = Schema(name=topic.typename, encoding="ros2msg", data=schema_text(topic.typename).encode())
        channel = Channel("/" + topic.name, schema=schema, message_encoding="cdr", context=self._context)
        self._channels[topic.name] = (topic, channel)
        self._names[channel.id()] = topic.name
        if topic.name in ALWAYS_TAPPED:
            self._tap.listen(topic)  # sim time for the Time capability, the scene's meshes: watched or not

    def _close(self, name: str) -> None:
        _, channel = self._channels.pop(name)
        del self._names[channel.id()]
        self._watchers.pop(name, None)
        self._tap.unlisten(name)
        channel.close()

    # --- viewers --------------------------------------------------------------------------

    def apply_changes(self) -> None:
        """Subscribe the keys that gained their first viewer, unsubscribe those that lost their last."""
        while True:
            try:
                change = self._changes.get_nowait()
            except queue.Empty:
                return
            name = self._names.get(change.channel)
            if name is None:
                continue  # its channel was closed since
            if change.subscribed:
                self._watch(name, change.client)
            else:
                self._unwatch(name, change.client)

    def _watch(self, name: str, client: int) -> None:
        watchers = self._watchers.setdefault(name, set())
        if client in watchers:
            return
        if watchers or name in ALWAYS_TAPPED:
            self._tap.unlisten(name)  # tapped afresh below: a latched key's latest reaches the newcomer too
        watchers.add(client)
        self._tap.listen(self._channels[name][0])
        logger.info("/%s: %d viewer%s", name, len(watchers), "" if len(watchers) == 1 else "s")

    def _unwatch(self, name: str, client: int) -> None:
        watchers = self._watchers.get(name, set())
        if client not in watchers:
            return
        watchers.discard(client)
        if not watchers and name not in ALWAYS_TAPPED:
            self._tap.unlisten(name)
        logger.info("/%s: %d viewer%s", name, len(watchers), "" if len(watchers) == 1 else "s")

    # --- messages -------------------------------------------------------------------------

    def pump(self, timeout: float) -> None:
        """Forward the queued samples (waiting up to `timeout` for the first, taking at most a queue's worth)."""
        sample = self._inbox.get(timeout)
        for _ in range(INBOX_SIZE):
            if sample is None:
                return
            self._forward(sample)
            sample = self._inbox.get(0.0)

    def _forward(self, sample: RawSample) -> None:
        if sample.topic == CLOCK_TOPIC:
            self._tick(sample)
        elif sample.topic == SCENE_TOPIC:
            self._assets.update(sample.data)
        entry = self._channels.get(sample.topic)
        if entry is None or not self._watchers.get(sample.topic):
            return  # the clock while nobody watches it, or a sample that was on its way when its key went
        entry[1].log(sample.data, log_time=self._log_time(sample))
        self.forwarded += 1

    def _tick(self, sample: RawSample) -> None:
        """Sim time from a clock sample, broadcast to the viewers."""
        now = sample.stamp_ns
        if now is None:
            return  # not met: the tap reads every Clock's time
        if self._clock.see(now) is not None:
            self._server.clear_session()  # the app drops the old run's timeline
        self._sim_ns = now
        self._server.broadcast_time(now)

    def _log_time(self, sample: RawSample) -> int:
        """The latest sim time seen: the clock's or the message's own stamp, whichever is later; 0 with neither."""
        return max((t for t in (self._sim_ns, sample.stamp_ns) if t is not None), default=0)

    # --- the end --------------------------------------------------------------------------

    def close(self) -> None:
        """Stop tapping and close every channel."""
        self._tap.close()
        for name in list(self._channels):
            self._close(name)

    def summary(self) -> str:
        dropped = self._tap.dropped
        text = f"forwarded {self.forwarded} messages; dropped {sum(dropped.values())} malformed samples"
        if dropped:
            text += " (" + ", ".join(f"{key}: {count}" for key, count in sorted(dropped.items())) + ")"
        if self._inbox.overwritten:
            text += f"; let {self._inbox.overwritten} samples go (the loop fell behind)"
        return text


def _identity(topic: Topic | None) -> tuple[str, str] | None:
    """What a channel stands for: its key and type (not who else uses the key)."""
    return None if topic is None else (topic.key, topic.typename)


def _changes_text(new: Sequence[Topic], gone: Sequence[str]) -> str:
    parts = []
    if new:
        parts.append("new: " + " ".join("/" + topic.name for topic in new))
    if gone:
        parts.append("gone: " + " ".join("/" + name for name in sorted(gone)))
    return "; ".join(parts)


def _ws_url(host: str, port: int) -> str:
    return f"ws://[{host}]:{port}" if ":" in host else f"ws://{host}:{port}"


def _require_sdk() -> None:
    """The SDK is an optional extra: without it, one line saying how to install it."""
    try:
        import foxglove  # noqa: F401
    except ImportError:
        raise ClientError(NEEDS_EXTRA) from None


def _start_server(
    namespace: str, listener: Listener, context: foxglove.Context, assets: SceneAssets
) -> WebSocketServer:
    """Foxglove's WebSocket server with the Time capability and asset fetch, on a private loopback port behind the front."""
    import foxglove
    from foxglove.websocket import Capability

    try:
        return foxglove.start_server(
            name=f"simbot {namespace}" if namespace else "simbot",
            host=LOOPBACK,
            port=0,
            capabilities=[Capability.Time],  # an asset handler adds the Assets capability
            server_listener=cast("ServerListener", listener),  # has the callbacks a server without ClientPublish calls
            asset_handler=assets.fetch,
            context=context,
        )
    except RuntimeError as exc:
        reason = str(exc).removeprefix("FoxgloveError: ")
        raise ClientError(f"cannot start Foxglove's server on {LOOPBACK}: {reason}") from None


def _bind_front(host: str, port: int) -> SubprotocolFront:
    """The front where the user asked, taking both subprotocols; a port in use (or a bad host) is a ClientError."""
    front = SubprotocolFront(host, port)
    try:
        front.bind()
    except OSError as exc:
        front.stop()
        raise ClientError(f"cannot serve on {host} port {port} (--host, --port): {exc.strerror or exc}") from None
    return front


def run(node: Node, stop: threading.Event, host: str, port: int, namespace: str) -> int:
    """Serves the bus (its `namespace`) to Foxglove on `host`:`port` (0: a free one) until `stop`."""
    import foxglove

    listener = Listener()
    context = foxglove.Context()
    assets = SceneAssets()
    front = _bind_front(host, port)
    try:
        server = _start_server(namespace, listener, context, assets)
    except ClientError:
        front.stop()
        raise
    front.serve(server.port)
    bridge = Bridge(node, server, context, listener, assets)
    logger.info("serving the bus on %s: in Foxglove, Open connection → Foxglove WebSocket", _ws_url(host, front.port))
    next_graph = 0.0
    try:
        while not stop.is_set():
            if time.monotonic() >= next_graph:
                bridge.refresh_graph()
                next_graph = time.monotonic() + GRAPH_PERIOD_S
            bridge.apply_changes()
            bridge.pump(WAIT_S)
    finally:
        front.stop()
        server.stop()
        bridge.close()
    logger.info("%s", bridge.summary())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot foxglove [--host H] [--port P]`."""
    parser = client_parser(
        "simbot foxglove", "Serve the live bus to the Foxglove app over Foxglove's WebSocket protocol."
    )
    parser.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help=f"address to serve on (default {DEFAULT_HOST}, this machine only; 0.0.0.0 serves every interface)",
    )
    parser.add_argument(
        "--port",
        type=whole(0, 65535),
        default=DEFAULT_PORT,
        help=f"TCP port to serve on (default {DEFAULT_PORT}; 0 picks a free one)",
    )
    return run_client(
        parser, argv, lambda args, node, stop: run(node, stop, args.host, args.port, args.namespace), check=_require_sdk
    )


if __name__ == "__main__":
    sys.exit(main())
