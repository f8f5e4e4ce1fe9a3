"""`simbot ros2`: the bus as ROS 2 topics on DDS, through rclpy, CDR bytes unchanged.

What zenoh-bridge-ros2dds does, in Python, so that a ROS 2 node (RViz2, Nav2, slam_toolbox)
sees simbot with nothing more than rclpy:

- Every key someone publishes in the namespace gets an rclpy publisher of its ROS 2 type on the
  topic `/<key>` (namespace kept). Zenoh's payload goes to `Publisher.publish(bytes)` as it
  came: the bridge never decodes (the server wrote CDR, DDS carries CDR). It publishes from the
  Zenoh callback itself: rclpy's publish is thread-safe and copies the bytes into DDS at once, so
  a queue and a second thread would only add a hop to every message.
- Every input key (the server's, from its world state: `cmd_vel`, `attach`, `detach` and any its
  systems declare; and any key a simbot program subscribes to that nobody publishes) gets a raw
  rclpy subscription whose bytes go onto Zenoh unchanged. The server checks them and counts
  what is malformed, as it does for any input.
- QoS: data reliable, volatile, keep-last 10 (default and sensor-data subscribers both match);
  latched keys (a plain Zenoh `get` answers them: `tf_static`, `robot_description`,
  `detachable_joint/state`, `scene`, which RViz's MarkerArray display shows) reliable, transient-local, depth 1, so a late-joining node gets them.
- A data key is subscribed on Zenoh only while a DDS subscriber matches its publisher: cameras
  render only while a ROS node watches them, and an idle bridge costs the simulation nothing.
  Latched keys are always subscribed (the DDS publisher must hold the latest for late joiners).
- A key published and subscribed at once (`cmd_vel` while `simbot teleop` drives) is carried
  both ways without echoes: the Zenoh side neither hears its own puts (Locality.REMOTE) nor, on
  DDS, takes its own publisher's messages (their publisher gid is the bridge's own).
- Sim time going back on `clock` (the server restarted, or the world was reset: sim time starts
  again from zero) is one warning line per jump. The bridge keeps nothing keyed on time: it
  carries the new server's `/clock`, and ROS nodes on `use_sim_time` handle the jump as ROS does
  (rclpy's time source runs the clock's jump callbacks, tf2 clears its buffers). A killed server's
  keys leave the graph, so their routes close (DDS publishers, latched history and all) and open
  again for the new server's; a route a restart did not close carries the new server's data as
  it comes, latched keys too (the advanced subscriber takes a late publisher's latest).
- A type whose generated type support is not importable (with the pip wheels: `tf2_msgs`, so
  `/tf` and `/tf_static`; `vision_msgs`, so the bounding-box cameras' boxes: the package index has
  no wheel of either) is one warning naming the topic and the type; the rest carries on. With a
  sourced ROS 2 install that has them, they are carried like the others.

The bridge's Zenoh entities are not announced on simbot's graph: announcing them would make the
bridge see its own `cmd_vel` publisher and carry it back out.
"""

from __future__ import annotations

import importlib
import logging
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import zenoh
import zenoh.ext

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.codec import DecodeError, decode

from .common import CLOCK, ClientError, SimTimeWatch, StatusLine, client_parser, run_client
from .record import Selection
from .state import NoWorld, ask
from .topics import Topic, latched, live_topics, topic_name, world_names

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node as RosNode
    from rclpy.publisher import Publisher as RosPublisher
    from rclpy.qos import QoSProfile
    from rclpy.subscription import MessageInfo
    from rclpy.subscription import Subscription as RosSubscription

logger = logging.getLogger(__name__)

NEEDS_RCLPY = "needs rclpy: source a ROS 2 install (Humble, Jazzy, Kilted), or pip install 'simbot[ros2]'"
NODE_NAME = "simbot_ros2"
DEPTH = 10
GRAPH_PERIOD_S = 1.0
WATCH_PERIOD_S = 0.2
SPIN_S = 0.1
STATE_TIMEOUT_S = 2.0
CDR = zenoh.Encoding.APPLICATION_CDR


class MissingTypeSupport(LookupError):
    """A ROS 2 type whose generated Python type support cannot be imported; str() says why."""


def ros_type(typename: str) -> type[Any]:
    """The rclpy message class of `pkg/msg/Name`, from wherever it is importable (a sourced install, the wheels)."""
    package, kind, name = typename.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError) as exc:
        raise MissingTypeSupport(f"no type support for {typename} ({exc})") from None


def qos(latched_key: bool) -> QoSProfile:
    """Reliable keep-last 10, volatile; reliable keep-last 1, transient-local for a latched key."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    durability = DurabilityPolicy.TRANSIENT_LOCAL if latched_key else DurabilityPolicy.VOLATILE
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1 if latched_key else DEPTH,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=durability,
    )


class Counter:
    """Messages carried one way, counted from any thread; `rate` gives messages per second since it was last read."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.total = 0
        self._read = (time.monotonic(), 0)

    def add(self) -> None:
        with self._lock:
            self.total += 1

    def rate(self) -> float:
        now = time.monotonic()
        with self._lock:
            then, count = self._read
            self._read = (now, self.total)
            return (self.total - count) / max(now - then, 1e-9)


class Outbound:
    """One published key carried to DDS: an rclpy publisher fed Zenoh's payloads as they are."""

    def __init__(
        self, session: zenoh.Session, topic: Topic, publisher: RosPublisher[Any], latched_key: bool, counter: Counter
    ) -> None:
        self.topic = topic
        self.latched = latched_key
        self.publisher = publisher
        self._session = session
        self._counter = counter
        self._subscriber: Any = None

    @property
    def subscribed(self) -> bool:
        """Whether the key is subscribed on Zenoh now."""
        return self._subscriber is not None

    def subscribe(self) -> None:
        """Take the key's payloads from Zenoh (the latest at once for a latched key); never our own puts."""
        if self._subscriber is not None:
            return
        if self.latched:
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1)
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                self._session, self.topic.data_key, self._on_sample, history=history
            )
        else:
            self._subscriber = self._session.declare_subscriber(
                self.topic.data_key, self._on_sample, allowed_origin=zenoh.Locality.REMOTE
            )

    def unsubscribe(self) -> None:
        subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            subscriber.undeclare()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh thread: the bytes straight to DDS."""
        if sample.kind != zenoh.SampleKind.PUT:
            return
        try:
            self.publisher.publish(sample.payload.to_bytes())
        except (
            RuntimeError
        ) as exc:  # rclpy's InvalidHandle: the publisher was destroyed while this sample was on its way
            logger.debug("/%s: not published: %s", self.topic.key, exc)
            return
        self._counter.add()


class Inbound:
    """One input key carried from DDS: a raw rclpy subscription whose payloads go onto Zenoh unchanged."""

    def __init__(
        self, session: zenoh.Session, ros: RosNode, topic: Topic, msgtype: type[Any], counter: Counter
    ) -> None:
        self.topic = topic
        self._ros = ros
        self._counter = counter
        self._own: set[bytes] = set()
        self._others: set[bytes] = set()
        self._publisher = session.declare_publisher(
            topic.data_key,
            encoding=CDR.with_schema(topic.typename),
            congestion_control=zenoh.CongestionControl.BLOCK,
            allowed_destination=zenoh.Locality.REMOTE,
        )
        self.subscription: RosSubscription[Any] = ros.create_subscription(
            msgtype, "/" + topic.key, self._on_message, qos(False), raw=True
        )

    def _on_message(self, data: bytes, info: MessageInfo) -> None:
        """Executor (the loop): put the bytes on Zenoh, unless the bridge's own DDS publisher sent them."""
        gid = bytes((info["publisher_gid"] or {}).get("data", b""))
        if self._is_own(gid):
            return
        self._publisher.put(data)
        self._counter.add()

    def _is_own(self, gid: bytes) -> bool:
        """Whether `gid` is one of the bridge's own publishers on this topic (the graph is asked once per publisher)."""
        if gid not in self._own and gid not in self._others:
            for info in self._ros.get_publishers_info_by_topic("/" + self.topic.key):
                if info.node_name == self._ros.get_name() and info.node_namespace == self._ros.get_namespace():
                    self._own.add(bytes(info.endpoint_gid))
            if gid not in self._own:
                self._others.add(gid)
        return gid in self._own

    def close(self) -> None:
        self._ros.destroy_subscription(self.subscription)
        self._publisher.undeclare()


@dataclass
class Routes:
    """What the bridge carries now, each way, by topic name."""

    outbound: dict[str, Outbound]
    inbound: dict[str, Inbound]


class Bridge:
    """The routes of the live keys, their Zenoh subscriptions while watched, and the counts for the status line."""

    def __init__(self, node: Node, ros: RosNode, selection: Selection) -> None:
        self._node = node
        self._ros = ros
        self._selection = selection
        self.routes = Routes({}, {})
        self.to_dds = Counter()
        self.from_dds = Counter()
        self._skipped: set[tuple[str, str]] = set()
        self._inputs: set[str] = set()
        self._graph: frozenset[tuple[str, tuple[str, ...]]] = frozenset()
        self._rewind = SimTimeWatch()
        # a plain Zenoh subscriber, not node.subscribe: that one would announce the bridge on the graph
        self._clock = node.session.declare_subscriber(node.data_key("/clock", CLOCK), self._on_clock)

    def _on_clock(self, sample: zenoh.Sample) -> None:
        """Zenoh thread: the tick's sim time to the rewind detector."""
        try:
            ns = messages.stamp_ns(decode(sample.payload.to_bytes(), CLOCK).clock)
        except DecodeError as exc:
            logger.debug("/%s: %s", sample.key_expr, exc)
            return
        self._rewind.see(ns)

    # --- the graph ------------------------------------------------------------------------

    def refresh_graph(self) -> None:
        """Routes for the keys live now: new ones made, gone ones (or ones that changed type) closed."""
        topics = {name: topic for name, topic in live_topics(self._node).items() if self._selection.chosen(name)}
        graph = frozenset((topic.key, topic.kinds) for topic in topics.values())
        if graph != self._graph:
            self._graph = graph
            self._inputs = self._input_names(topics)
        outputs = {name: topic for name, topic in topics.items() if "pub" in topic.kinds}
        inputs = {name: topics[name] for name in self._inputs if name in topics}
        self._update(self.routes.outbound, outputs, self._open_outbound, self._close_outbound)
        self._update(self.routes.inbound, inputs, self._open_inbound, Inbound.close)

    def _input_names(self, topics: dict[str, Topic]) -> set[str]:
        """The server's input keys (its world state counts them) and the keys subscribed that nobody publishes."""
        names = {name for name, topic in topics.items() if "sub" in topic.kinds and "pub" not in topic.kinds}
        for world in world_names(topics.values()):
            try:
                received = ask(self._node, world, STATE_TIMEOUT_S).get("received", {})
            except NoWorld as exc:
                logger.warning("cannot read the inputs of world %s: %s", world, exc)
                continue
            names.update(topic_name(key, self._node.namespace) for key in received)
        return names

    def _update(
        self,
        routes: dict[str, Any],
        live: dict[str, Topic],
        open_route: Callable[[list[Topic]], None],
        close: Callable[[Any], None],
    ) -> None:
        gone = [name for name, route in routes.items() if _identity(live.get(name)) != _identity(route.topic)]
        for name in gone:
            route = routes.pop(name)
            close(route)
            logger.info("stopped carrying /%s", route.topic.key)
        new = [topic for name, topic in sorted(live.items()) if name not in routes and self._supported(topic)]
        if new:
            open_route(new)

    def _supported(self, topic: Topic) -> bool:
        """Whether rclpy has the topic's type; one warning per topic and type otherwise."""
        try:
            ros_type(topic.typename)
        except MissingTypeSupport as exc:
            if (topic.name, topic.typename) not in self._skipped:
                self._skipped.add((topic.name, topic.typename))
                logger.warning("not carrying /%s (%s): %s", topic.key, topic.typename, exc)
            return False
        return True

    def _open_outbound(self, topics: list[Topic]) -> None:
        held = latched(self._node.session, [topic.data_key for topic in topics])
        for topic in topics:
            latched_key = topic.data_key in held
            publisher = self._ros.create_publisher(ros_type(topic.typename), "/" + topic.key, qos(latched_key))
            route = self.routes.outbound[topic.name] = Outbound(
                self._node.session, topic, publisher, latched_key, self.to_dds
            )
            if latched_key:
                route.subscribe()
            logger.info("/%s → DDS (%s%s)", topic.key, topic.typename, ", transient local" if latched_key else "")

    def _close_outbound(self, route: Outbound) -> None:
        route.unsubscribe()
        self._ros.destroy_publisher(route.publisher)

    def _open_inbound(self, topics: list[Topic]) -> None:
        for topic in topics:
            self.routes.inbound[topic.name] = Inbound(
                self._node.session, self._ros, topic, ros_type(topic.typename), self.from_dds
            )
            logger.info("/%s ← DDS (%s)", topic.key, topic.typename)

    # --- watchers -------------------------------------------------------------------------

    def watch(self) -> None:
        """Subscribe the data keys a DDS subscriber now matches on Zenoh, unsubscribe those none does."""
        for name, route in self.routes.outbound.items():
            if route.latched:
                continue
            own = 1 if name in self.routes.inbound else 0  # the bridge's own subscription to a key carried both ways
            watched = route.publisher.get_subscription_count() > own
            if watched and not route.subscribed:
                route.subscribe()
                logger.info("/%s: watched on DDS", route.topic.key)
            elif not watched and route.subscribed:
                route.unsubscribe()
                logger.info("/%s: no DDS subscriber left", route.topic.key)

    # --- the end --------------------------------------------------------------------------

    def status(self) -> str:
        watched = sum(route.subscribed for route in self.routes.outbound.values())
        return (
            f"{len(self.routes.outbound)} topics to DDS ({watched} subscribed), {len(self.routes.inbound)} from DDS; "
            f"{self.to_dds.rate():.0f} msg/s to DDS, {self.from_dds.rate():.0f} msg/s from DDS"
        )

    def close(self) -> None:
        self._clock.undeclare()
        for route in self.routes.outbound.values():
            self._close_outbound(route)
        for inbound in self.routes.inbound.values():
            inbound.close()
        self.routes = Routes({}, {})

    def summary(self) -> str:
        return f"carried {self.to_dds.total} messages to DDS and {self.from_dds.total} from DDS"


def _identity(topic: Topic | None) -> tuple[str, str] | None:
    """What a route stands for: its key and type (not who else uses the key)."""
    return None if topic is None else (topic.key, topic.typename)


def _require_rclpy() -> None:
    """rclpy is optional: without it, one line saying where to get it."""
    try:
        import rclpy  # noqa: F401
    except ImportError:
        raise ClientError(NEEDS_RCLPY) from None


def _loop(bridge: Bridge, executor: Executor, stop: threading.Event) -> None:
    """Spin the DDS side; look at the graph every second and at the DDS subscribers five times a second."""
    status = StatusLine()
    next_graph = next_watch = 0.0
    while not stop.is_set():
        now = time.monotonic()
        if now >= next_graph:
            bridge.refresh_graph()
            next_graph = now + GRAPH_PERIOD_S
        if now >= next_watch:
            bridge.watch()
            next_watch = now + WATCH_PERIOD_S
        executor.spin_once(timeout_sec=SPIN_S)
        status.show(now, bridge.status)


def run(node: Node, stop: threading.Event, selection: Selection, dds_domain: int | None) -> int:
    """Carries the selected keys between the bus and DDS domain `dds_domain` (None: ROS_DOMAIN_ID's) until `stop`."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(  # Ctrl-C is run_client's
        args=[], context=context, domain_id=dds_domain, signal_handler_options=SignalHandlerOptions.NO
    )
    ros = rclpy.create_node(NODE_NAME, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(ros)
    bridge = Bridge(node, ros, selection)
    try:
        _loop(bridge, executor, stop)
    finally:
        bridge.close()
        executor.shutdown()
        ros.destroy_node()
        rclpy.shutdown(context=context)
    logger.info("%s", bridge.summary())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot ros2 [--allow GLOB]… [--deny GLOB]…`."""
    parser = client_parser("simbot ros2", "Carry the bus to ROS 2 (DDS) and back through rclpy, CDR bytes unchanged.")
    parser.add_argument(
        "--allow",
        action="append",
        default=[],
        metavar="GLOB",
        help="carry only keys matching (repeatable; default all)",
    )
    parser.add_argument(
        "--deny", action="append", default=[], metavar="GLOB", help="never carry keys matching (repeatable)"
    )
    parser.add_argument(
        "--dds-domain",
        type=number(int, at_least_zero=True),
        metavar="N",
        help="the DDS domain to carry the bus into (default: ROS_DOMAIN_ID, the bus's own domain)",
    )
    return run_client(
        parser,
        argv,
        lambda args, node, stop: run(node, stop, Selection(args.allow, args.deny), args.dds_domain),
        check=_require_rclpy,
    )


if __name__ == "__main__":
    sys.exit(main())
