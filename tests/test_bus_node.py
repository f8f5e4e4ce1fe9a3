"""Bus nodes on real Zenoh sessions over loopback: pub/sub, latched topics, inboxes, JSON services, options."""

from __future__ import annotations

import argparse
import json
import logging
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
import zenoh
from bus_helpers import BoundSocket, endpoint, free_port, node_pair, own_sockets, unique_namespace, wait_until

from simbot.bus import (
    BadRequest,
    BusConfigError,
    BusOpenError,
    BusOptions,
    EncodeError,
    ForkedSessionError,
    Node,
    Publisher,
    Queryable,
    Request,
    ServiceError,
    add_bus_arguments,
    encode,
    zenoh_config,
)
from simbot.bus import messages as m
from simbot.bus.rmw import parse_attachment

TWIST = "geometry_msgs/msg/Twist"
STRING = "std_msgs/msg/String"


def test_twist_round_trip_client_to_server_and_back() -> None:
    """cmd_vel from a client reaches the server decoded; odom-like data flows the other way."""
    with node_pair() as pair:
        got: list[Any] = []
        subscription = pair.server.subscribe("/cmd_vel", TWIST, got.append)
        publisher = pair.client.publisher("/cmd_vel", TWIST)
        wait_until(lambda: publisher.has_subscribers, what="the server's cmd_vel subscription")
        publisher.put(m.twist((0.5, 0.0, 0.0), (0.0, 0.0, -0.25)))
        wait_until(lambda: got, what="the Twist")
        assert got[0].linear.x == pytest.approx(0.5, abs=1e-12)
        assert got[0].angular.z == pytest.approx(-0.25, abs=1e-12)
        assert (subscription.received, subscription.dropped) == (1, 0)

        back: list[Any] = []
        pair.client.subscribe("odom_twist", TWIST, back.append)
        server_publisher = pair.server.publisher("odom_twist", TWIST)
        wait_until(lambda: server_publisher.has_subscribers, what="the client's subscription")
        server_publisher.put(m.twist((0.1, 0.2, 0.3), (0.4, 0.5, 0.6)))
        wait_until(lambda: back, what="the server's Twist")
        linear, angular = back[0].linear, back[0].angular
        assert [linear.x, linear.y, linear.z, angular.x, angular.y, angular.z] == pytest.approx(
            [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
        )


def test_keys_carry_the_namespace() -> None:
    """A node's keys are rmw_zenoh's: domain, namespace + topic, DDS type, type hash; samples carry the
    CDR encoding with the type name and rmw_zenoh's 33-byte attachment, numbered from 1."""
    with node_pair() as pair:
        assert pair.server.key("/tf_static") == f"{pair.server.namespace}/tf_static"
        samples: list[zenoh.Sample] = []
        pair.client.session.declare_subscriber(f"0/{pair.client.namespace}/**", samples.append)
        publisher = pair.server.publisher("/clock", "rosgraph_msgs/msg/Clock")
        wait_until(lambda: publisher.has_subscribers, what="the plain subscriber")
        before_ns = time.time_ns()
        publisher.put(m.clock(2_000_000_001))
        publisher.put(m.clock(2_000_000_002))
        after_ns = time.time_ns()
        wait_until(lambda: len(samples) == 2, what="the Clock samples")
        assert str(samples[0].key_expr) == (
            f"0/{pair.client.namespace}/clock/rosgraph_msgs::msg::dds_::Clock_/"
            "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"
        )
        assert str(samples[0].encoding) == "application/cdr;rosgraph_msgs/msg/Clock"
        assert samples[0].payload.to_bytes() == encode(m.clock(2_000_000_001))
        attachments = [parse_attachment(s.attachment.to_bytes()) for s in samples if s.attachment is not None]
        assert [a[0] for a in attachments] == [1, 2] and attachments[0][2] == attachments[1][2]
        assert before_ns <= attachments[0][1] <= after_ns, "the source timestamp is the wall clock's at the put"


def test_latched_topic_reaches_a_late_joiner_exactly_once() -> None:
    """A subscriber that joins after the puts gets the latest value once, then every later put."""
    with node_pair() as pair:
        publisher = pair.server.publisher("/robot_description", STRING, latched=True, drop=False)
        publisher.put(m.string("<robot name='v1'/>"))
        publisher.put(m.string("<robot name='v2'/>"))
        got: list[str] = []
        pair.client.subscribe("/robot_description", STRING, lambda msg: got.append(msg.data), latched=True)
        wait_until(lambda: got, what="the latched value")
        publisher.put(m.string("<robot name='v3'/>"))
        wait_until(lambda: len(got) >= 2, what="the update")
        publisher.put(m.string("<robot name='v4'/>"))  # the marker: a duplicate of v2 or v3 comes before it or never
        wait_until(lambda: "<robot name='v4'/>" in got, what="the marker")
        assert got == ["<robot name='v2'/>", "<robot name='v3'/>", "<robot name='v4'/>"]


def test_latched_subscriber_before_the_publisher_and_across_a_server_restart() -> None:
    """Late-publisher detection: a subscriber gets the values of publishers that appear after it."""
    port, namespace = free_port(), unique_namespace()
    server_options = BusOptions(listen=(endpoint(port),), namespace=namespace)
    got: list[str] = []
    with Node(server_options, "server") as server:
        client = Node(BusOptions(connect=(endpoint(port),), namespace=namespace), "client")
        client.subscribe("tf_static_names", STRING, lambda msg: got.append(msg.data), latched=True)
        server.publisher("tf_static_names", STRING, latched=True).put(m.string("first"))
        wait_until(lambda: got == ["first"], what="the first server's value")
    with client, Node(server_options, "server") as restarted:
        restarted.publisher("tf_static_names", STRING, latched=True).put(
            m.string("second")
        )  # before the client reconnects
        wait_until(lambda: got == ["first", "second"], timeout=10.0, what="the restarted server's value")


def test_latched_topic_answers_a_plain_zenoh_get() -> None:
    """A plain Zenoh user reads the latest latched value with `get` on the key."""
    with node_pair() as pair:
        publisher = pair.server.publisher("detachable_joint/state", STRING, latched=True)
        publisher.put(m.string("detached"))
        publisher.put(m.string("attached"))
        replies = list(pair.client.session.get(pair.client.data_key("detachable_joint/state", STRING), timeout=2.0))
        payloads = [reply.ok.payload.to_bytes() for reply in replies if reply.ok is not None]
        assert payloads == [encode(m.string("attached"))]


def test_inbox_drains_in_order_and_counts_overflow() -> None:
    """Raw payloads queue up to maxlen (the oldest go first when full); drain returns and clears them."""
    with node_pair() as pair:
        inbox = pair.server.inbox("/cmd_vel", TWIST, maxlen=3)
        publisher = pair.client.publisher("/cmd_vel", TWIST, drop=False)
        wait_until(lambda: publisher.has_subscribers, what="the inbox subscription")
        for i in range(5):
            publisher.put(m.twist((float(i), 0.0, 0.0)))
        wait_until(lambda: inbox.overflowed == 2, what="two overflows")
        drained = inbox.drain()
        assert drained == [encode(m.twist((float(i), 0.0, 0.0))) for i in (2, 3, 4)]
        assert inbox.drain() == []


def test_garbage_is_counted_and_good_messages_still_arrive(caplog: pytest.LogCaptureFixture) -> None:
    """Undecodable payloads bump `dropped` with one rate-limited warning; the subscription keeps working."""
    caplog.set_level(logging.WARNING, logger="simbot.bus.node")
    with node_pair() as pair:
        got: list[Any] = []
        subscription = pair.server.subscribe("/cmd_vel", TWIST, got.append)
        publisher = pair.client.publisher("/cmd_vel", TWIST, drop=False)
        wait_until(lambda: publisher.has_subscribers, what="the cmd_vel subscription")
        publisher.put_raw(b"\x00\x01\x00\x00garbage")
        publisher.put(m.string("a String is not a Twist"))
        publisher.put_raw(encode(m.twist((1.0, 0.0, 0.0)))[:-3])  # truncated CDR
        wait_until(lambda: subscription.dropped == 3, what="three drops")
        publisher.put(m.twist((0.3, 0.0, 0.0)))
        wait_until(lambda: got, what="the good Twist")
        assert got[0].linear.x == pytest.approx(0.3)
        assert (subscription.received, subscription.dropped) == (1, 3)
    warnings = [r for r in caplog.records if "dropped a payload" in r.getMessage()]
    assert len(warnings) == 1
    assert "cmd_vel" in warnings[0].getMessage() and "geometry_msgs/msg/Twist" in warnings[0].getMessage()


def _answer_next(service: Queryable, answer: Callable[[Request], object], timeout: float = 5.0) -> Request:
    """Poll `service` until a request comes, answer it with `answer(request)`, return it."""
    requests: list[Request] = []

    def arrived() -> bool:
        requests.extend(service.poll())
        return bool(requests)

    wait_until(arrived, timeout, "a request")
    answer(requests[0])
    return requests[0]


def test_json_service_round_trip_and_deferred_reply() -> None:
    """call → poll → reply, the reply possibly sent later from another thread."""
    with node_pair() as pair, ThreadPoolExecutor(2) as pool:
        service = pair.server.queryable("world/control")
        assert service.poll() == []
        future = pool.submit(pair.client.call, "world/control", {"step": 3})
        request = _answer_next(service, lambda r: r.reply({"ok": True, "steps": r.json()["step"]}))
        assert future.result(timeout=5) == {"ok": True, "steps": 3}
        with pytest.raises(RuntimeError, match="already answered"):
            request.reply({"ok": True})

        start = time.monotonic()
        future = pool.submit(pair.client.call, "world/control", {"pause": True})
        _answer_next(service, lambda r: threading.Timer(0.3, r.reply, args=({"paused": True},)).start())
        assert future.result(timeout=5) == {"paused": True}
        assert time.monotonic() - start >= 0.3

        future = pool.submit(pair.client.call, "world/control", b"")  # no payload reads as {}
        _answer_next(service, lambda r: r.reply({"request": r.json()}))
        assert future.result(timeout=5) == {"request": {}}


def test_malformed_requests_are_bad_requests() -> None:
    """Malformed JSON or a non-object is BadRequest on the server; its error reply is a ServiceError."""
    with node_pair() as pair, ThreadPoolExecutor(1) as pool:
        service = pair.server.queryable("world/control")
        reasons: list[str] = []

        def reject(request: Request) -> None:
            with pytest.raises(BadRequest) as caught:
                request.json()
            reasons.append(str(caught.value))
            request.reply_error(str(caught.value))

        for payload, reason in ((b"{pause: true", "malformed JSON"), (b"[1, 2]", "expected a JSON object, got list")):
            future = pool.submit(pair.client.call, "world/control", payload)
            _answer_next(service, reject)
            with pytest.raises(ServiceError, match=reason):
                future.result(timeout=5)
            assert "\n" not in reasons[-1] and reasons[-1].startswith(pair.server.key("world/control"))


def test_call_times_out_naming_the_key() -> None:
    """No answer within the timeout (or no service at all) is a TimeoutError naming the key; the call
    waits as long as its timeout says: a longer timeout, timed in the same test, waits longer."""
    with node_pair() as pair:
        pair.server.queryable("world/silent")

        def unanswered(timeout: float) -> float:
            start = time.monotonic()
            with pytest.raises(TimeoutError, match=f"{pair.client.namespace}/world/silent"):
                pair.client.call("world/silent", {}, timeout=timeout)
            return time.monotonic() - start

        short, long = unanswered(0.5), unanswered(1.5)
        assert 0.4 < short < long and long > 1.2, (short, long)
        with pytest.raises(TimeoutError, match="world/none"):
            pair.client.call("world/none", {}, timeout=0.5)


def _tcp_listening(sockets: set[BoundSocket]) -> set[tuple[str, int]]:
    return {(s.address, s.port) for s in sockets if s.proto.startswith("tcp")}


def test_server_listens_only_on_its_loopback_port_and_client_on_nothing() -> None:
    """The secure default: one TCP listener at 127.0.0.1:PORT for the server, none for a client, no UDP."""
    before = own_sockets()
    port = free_port()
    namespace = unique_namespace()
    with Node(BusOptions(listen=(endpoint(port),), namespace=namespace), "server"):
        with_server = own_sockets()
        assert with_server - before == {BoundSocket("tcp", "127.0.0.1", port, "0A")}
        with Node(BusOptions(connect=(endpoint(port),), namespace=namespace), "client"):
            assert own_sockets() == with_server
    assert all(s.loopback for s in own_sockets() - before)


def test_default_configs_are_loopback_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without options: server peer on 127.0.0.1:7448, joining a ROS 2 router at rmw_zenohd's 7447 if
    one is there; client connects to the server; no multicast, timestamps."""
    monkeypatch.delenv("ZENOH_ROUTER_CONFIG_URI", raising=False)
    server = zenoh_config(BusOptions(), "server")
    client = zenoh_config(BusOptions(), "client")
    assert json.loads(server.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7448"]
    assert json.loads(server.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(client.get_json("listen/endpoints")) == []
    assert json.loads(client.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7448"]
    assert (json.loads(server.get_json("mode")), json.loads(client.get_json("mode"))) == ("peer", "client")
    for config in (server, client):
        assert json.loads(config.get_json("scouting/multicast/enabled")) is False
        assert json.loads(config.get_json("timestamping/enabled")) is True


def test_a_ros_hosts_router_domain_and_session_config_are_honoured(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ZENOH_ROUTER_CONFIG_URI says where the server finds the router; ZENOH_SESSION_CONFIG_URI is the
    config file of a program given none; ROS_DOMAIN_ID is the keys' domain; `--ros-router none` joins nothing."""
    router = tmp_path / "router.json5"
    router.write_text("{ mode: 'router', listen: { endpoints: ['tcp/[::]:7550'] } }\n")
    session = tmp_path / "session.json5"
    session.write_text("{ mode: 'peer', scouting: { multicast: { enabled: false } }, queries_default_timeout: 1234 }\n")
    monkeypatch.setenv("ZENOH_ROUTER_CONFIG_URI", str(router))
    monkeypatch.setenv("ZENOH_SESSION_CONFIG_URI", str(session))
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    parser = argparse.ArgumentParser()
    add_bus_arguments(parser)
    options = BusOptions.from_args(parser.parse_args(["--listen", "tcp/127.0.0.1:7551", "--ros-distro", "humble"]))
    assert (options.config_file, options.ros.domain_id, options.ros.distro) == (session, 42, "humble")
    server = zenoh_config(options, "server")
    assert json.loads(server.get_json("connect/endpoints")) == ["tcp/[::1]:7550"]
    assert json.loads(server.get_json("queries_default_timeout")) == 1234
    assert (
        options.ros.data_key("ns/odom", "nav_msgs/msg/Odometry")
        == "42/ns/odom/nav_msgs::msg::dds_::Odometry_/TypeHashNotSupported"
    )
    alone = BusOptions.from_args(parser.parse_args(["--ros-router", "none"]))
    assert json.loads(zenoh_config(alone, "server").get_json("connect/endpoints")) == []
    monkeypatch.setenv("ROS_DOMAIN_ID", "blue")
    with pytest.raises(BusConfigError, match=r"^ROS_DOMAIN_ID 'blue': not a number$"):
        BusOptions.from_args(parser.parse_args([]))


def test_options_from_the_command_line_and_a_config_file(tmp_path: Path) -> None:
    """--listen/--connect override; a config file's own settings are kept, the rest get our defaults."""
    parser = argparse.ArgumentParser()
    add_bus_arguments(parser)
    config_file = tmp_path / "zenoh.json5"
    config_file.write_text(
        "{ // JSON5, as Zenoh reads it\n  scouting: { multicast: { enabled: true } },\n  listen: { endpoints: ['tcp/127.0.0.1:0'] },\n}\n"
    )
    args = parser.parse_args(
        [
            "--connect",
            "tcp/127.0.0.1:7448",
            "--connect",
            "tcp/[::1]:7449",
            "--zenoh-config",
            str(config_file),
            "--namespace",
            "/robot1/",
        ]
    )
    options = BusOptions.from_args(args)
    assert options == BusOptions(
        connect=("tcp/127.0.0.1:7448", "tcp/[::1]:7449"), config_file=config_file, namespace="/robot1/"
    )
    config = zenoh_config(options, "client")
    assert json.loads(config.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7448", "tcp/[::1]:7449"]
    assert json.loads(config.get_json("listen/endpoints")) == ["tcp/127.0.0.1:0"]  # the file said so
    assert json.loads(config.get_json("scouting/multicast/enabled")) is True  # the file said so
    assert json.loads(config.get_json("mode")) == "client"
    assert BusOptions.from_args(parser.parse_args([])) == BusOptions()
    listen = zenoh_config(BusOptions.from_args(parser.parse_args(["--listen", "tcp/127.0.0.1:7500"])), "server")
    assert json.loads(listen.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7500"]


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (None, "no such Zenoh config file"),
        ("{ mode: ", "invalid Zenoh config"),
        ("{ no_such_section: 1 }", "invalid Zenoh config"),
    ],
)
def test_bad_zenoh_config_file_names_the_file(tmp_path: Path, content: str | None, reason: str) -> None:
    """A missing or unreadable --zenoh-config file is one BusConfigError line naming the file."""
    path = tmp_path / "bad.json5"
    if content is not None:
        path.write_text(content)
    with pytest.raises(BusConfigError, match=reason) as caught:
        Node(BusOptions(config_file=path), "server")
    assert str(caught.value).startswith(str(path)) and "\n" not in str(caught.value)


def test_bad_endpoints_and_namespace_name_the_option() -> None:
    """An endpoint Zenoh cannot parse names its option; so does a namespace with wildcards."""
    with pytest.raises(BusConfigError, match=r"^--listen '127\.0\.0\.1:7447': not a Zenoh endpoint"):
        zenoh_config(BusOptions(listen=("127.0.0.1:7447",)), "server")
    with pytest.raises(BusConfigError, match=r"^--connect 'bogus'"):
        zenoh_config(BusOptions(connect=("tcp/127.0.0.1:7447", "bogus")), "client")
    with pytest.raises(BusConfigError, match=r"^--namespace 'robot\*'"):
        BusOptions(namespace="robot*")


def test_open_failures_are_one_line_bus_open_errors() -> None:
    """A port already in use, or no server within the client's connect timeout: BusOpenError, after as
    long as that timeout says (a longer one, timed in the same test, takes longer)."""
    port = free_port()
    with Node(BusOptions(listen=(endpoint(port),)), "server"):
        with pytest.raises(BusOpenError, match="server") as caught:
            Node(BusOptions(listen=(endpoint(port),)), "server")
        assert "\n" not in str(caught.value)

    def unconnected(timeout: float) -> float:
        start = time.monotonic()
        with pytest.raises(BusOpenError, match="client"):
            Node(BusOptions(connect=(endpoint(free_port()),), connect_timeout=timeout), "client")
        return time.monotonic() - start

    short, long = unconnected(0.3), unconnected(1.0)
    assert short < long, f"a client gave up after {short:.2f} s of a 0.3 s connect timeout, {long:.2f} s of 1.0 s"


def test_a_process_forked_after_zenoh_started_is_told_at_once_not_left_to_hang() -> None:
    """A child forked from a process with a live session raises ForkedSessionError naming 'spawn'
    before it touches Zenoh (its threads are not in the child: a session there hangs)."""
    options = BusOptions(listen=(endpoint(free_port()),), namespace=unique_namespace())
    with Node(options, "server"):
        read, write = os.pipe()
        child = os.fork()
        if child == 0:  # the child: report how asking for a session went, and leave without cleanup
            os.close(read)
            try:
                Node(BusOptions(connect=options.listen, namespace=options.namespace), "client")
                outcome = "opened"
            except ForkedSessionError as exc:
                outcome = str(exc)
            os.write(write, outcome.encode())
            os._exit(0)
        os.close(write)
        with os.fdopen(read) as pipe:
            outcome = pipe.read()
        _, status = os.waitpid(child, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert outcome.startswith("this process was forked") and "'spawn'" in outcome, outcome


def test_who_listens_is_told_not_polled_and_a_watched_only_publisher_sends_nothing_unheard() -> None:
    """Zenoh's matching listener keeps `has_subscribers`: it turns true when another session
    subscribes and false when it leaves; a `watched_only` publisher (the server's) neither encodes
    nor puts while no one matches (a message it could not encode passes unnoticed, then fails once
    someone listens), and a later subscriber gets what is put from then on."""
    with node_pair() as pair:
        publisher = pair.server.publisher("fleet_scan", TWIST, watched_only=True)
        assert not publisher.has_subscribers
        publisher.put({"linear": 0.5})  # not a message, and not encoded: no one to send it to
        got: list[Any] = []
        subscription = pair.client.subscribe("fleet_scan", TWIST, got.append)
        wait_until(lambda: publisher.has_subscribers, what="the matching listener's news of the subscriber")
        with pytest.raises(EncodeError, match="not a rosbags message"):
            publisher.put({"linear": 0.5})
        publisher.put(m.twist((1.5, 0.0, 0.0), (0.0, 0.0, 0.0)))
        wait_until(lambda: got, what="the Twist put after the subscriber came")
        assert [msg.linear.x for msg in got] == [1.5]
        subscription.close()
        wait_until(lambda: not publisher.has_subscribers, what="the matching listener's news that it left")


def test_a_request_sees_every_subscriber_declared_before_it() -> None:
    """World control refreshes what the publishers know (`Node.refresh_subscribers`) before the
    steps a request asks for: a subscriber declared before the request is then seen every time,
    even by a request handled the instant it arrives, where the matching listener alone hears of
    it some time later (14 of 100 measured; issue 48)."""
    seen: list[bool] = []
    with node_pair() as pair:
        publishers: list[Any] = []

        def handle(query: zenoh.Query) -> None:  # on Zenoh's thread, as soon as the request arrives
            pair.server.refresh_subscribers()
            seen.append(publishers[-1].has_subscribers)
            query.reply(query.key_expr, b"{}")

        control = pair.server.session.declare_queryable(pair.server.key("/probe_control"), handle)
        for attempt in range(50):
            publishers.append(pair.server.publisher(f"probe_{attempt}", TWIST, watched_only=True))
            subscriber = pair.client.subscribe(f"probe_{attempt}", TWIST, lambda msg: None)
            list(pair.client.session.get(pair.server.key("/probe_control"), timeout=10.0))
            subscriber.close()
        control.undeclare()
    assert seen == [True] * 50


def _threads() -> int:
    """Every thread of this process, Zenoh's and Python's alike."""
    return len(os.listdir("/proc/self/task"))


def test_a_fleets_publishers_and_inboxes_start_no_thread_each_and_still_hear_their_peers() -> None:
    """A server's publisher learns of subscribers through a matching listener and its inbox only
    queues: both run on Zenoh's own threads, so a hundred of them start no thread of their own
    (zenoh-python's default starts one a callback: 28 a tug, 28 000 for a thousand). The news
    still arrives: a subscriber makes the publishers match, and a put reaches every inbox."""
    with node_pair() as pair:
        before = _threads()
        publishers = [pair.server.publisher(f"tug_{k}/odom", TWIST) for k in range(100)]
        inboxes = [pair.server.inbox(f"tug_{k}/cmd_vel", TWIST) for k in range(100)]
        latched = [pair.server.publisher(f"tug_{k}/robot_description", STRING, latched=True) for k in range(10)]
        assert _threads() - before <= 2, f"{_threads() - before} threads for 210 declarations"
        pair.client.subscribe("tug_7/odom", TWIST, lambda msg: None)
        wait_until(lambda: publishers[7].refresh() and publishers[7].has_subscribers, what="tug_7's subscriber")
        assert not publishers[8].has_subscribers
        senders = [pair.client.publisher(f"tug_{k}/cmd_vel", TWIST) for k in (3, 99)]
        for sender in senders:

            def matched(sender: Publisher = sender) -> bool:
                return sender.has_subscribers

            wait_until(matched, what="the server's inbox")
            sender.put(m.twist((0.5, 0.0, 0.0), (0.0, 0.0, 0.0)))
        wait_until(lambda: inboxes[3].received == 1 and inboxes[99].received == 1, what="both commands")
        latched[4].put(m.string("<robot/>"))
        replies = list(pair.client.session.get(latched[4].data_key, timeout=2.0))
        assert [reply.ok is not None for reply in replies] == [True]


def test_publishers_declared_while_a_world_loads_follow_who_listens_from_its_end() -> None:
    """Within `listening_later` a publisher is taken to be watched (nothing publishes while a world
    loads) and stays among those a step request refreshes; from its end it follows its subscribers:
    none at first, then the one a client declares."""
    with node_pair() as pair:
        with pair.server.listening_later():
            odom = pair.server.publisher("tug_1/odom", TWIST, watched_only=True)
            assert odom.has_subscribers
            pair.server.refresh_subscribers()
            pair.server.publisher("tug_2/odom", TWIST, watched_only=True).close()  # its model failed to build
        assert odom in pair.server._publishers, "dropped from the refresh before it listened"
        wait_until(lambda: not odom.has_subscribers, what="no subscriber once it listens")
        pair.client.subscribe("tug_1/odom", TWIST, lambda msg: None)
        wait_until(lambda: odom.refresh() and odom.has_subscribers, what="the client's subscriber")


def test_watching_counts_each_change_of_who_subscribes() -> None:
    """A node's `Watching.generation` moves on when a first subscriber comes to one of its publishers
    and when the last one leaves, and stands still otherwise: what holds of every `has_subscribers`
    holds while it does (the rendering system looks for watched cameras again only then). A new
    publisher is a change too: what it says is news."""
    with node_pair() as pair:
        publisher = pair.server.publisher("watched_scan", TWIST, watched_only=True)
        other = pair.server.publisher("unwatched_scan", TWIST)
        wait_until(lambda: not publisher.has_subscribers, what="no subscriber at first")
        quiet = pair.server.watching.generation
        other.put(m.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
        assert not publisher.has_subscribers and not other.has_subscribers
        assert pair.server.watching.generation == quiet, "putting and asking change nothing"
        subscriber = pair.client.subscribe("watched_scan", TWIST, lambda msg: None)
        wait_until(lambda: pair.server.watching.generation != quiet, what="the first subscriber's change")
        assert publisher.has_subscribers
        came = pair.server.watching.generation
        subscriber.close()
        wait_until(lambda: pair.server.watching.generation != came, what="the last subscriber's leaving")
        wait_until(lambda: not publisher.has_subscribers, what="no subscriber again")
