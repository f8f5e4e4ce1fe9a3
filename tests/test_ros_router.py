"""simbot beside a ROS 2 host's Zenoh router (issue 38, item 5): the server leaves the router's
port free, joins the router at `--ros-router` whether it is up before or after the server, and a
client of the router alone then sees the server's topics on the graph and gets their samples:
one graph, never a silent split. The router here is a Zenoh session in router mode on a fresh
loopback port, as rmw_zenohd is one on 7447; multicast scouting off, 127.0.0.1 only.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from contextlib import contextmanager

import zenoh
from bus_helpers import endpoint, free_port
from server_helpers import payload, raw_samples, running_server

from simbot.bus.graph import discover
from simbot.bus.rmw import RosGraph

JOIN_S = 20.0
"""How long the server may take to reach a router that came up after it (Zenoh retries at 1-4 s)."""


def _session(mode: str, listen: list[str], connect: list[str]) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


@contextmanager
def ros_router(port: int) -> Iterator[str]:
    """A Zenoh router listening on 127.0.0.1:`port`, as rmw_zenohd listens on 7447."""
    at = endpoint(port)
    with _session("router", [at], []):
        yield at


def _odom_through(router_at: str, namespace: str) -> tuple[float, list[str]]:
    """(seconds until a client of the router alone got the server's odom, the topics it saw on the graph)."""
    with _session("client", [], [router_at]) as client:
        start = time.monotonic()
        with raw_samples(client, RosGraph().any_type_key(f"{namespace}/odom"), payload) as odoms:
            odoms.wait_count(1, JOIN_S, "the server's odom through the router")
            waited = time.monotonic() - start
        topics = sorted({e.key for e in discover(client, namespace) if e.kind == "pub"})
    return waited, topics


def test_the_server_joins_a_router_that_is_up_before_it() -> None:
    port = free_port()
    with ros_router(port) as at, running_server("empty", "realtime", extra=("--ros-router", at)) as sim:
        waited, topics = _odom_through(at, sim.namespace)
    assert f"{sim.namespace}/odom" in topics and f"{sim.namespace}/clock" in topics, topics
    print(
        f"\nmeasured: odom through a router up before the server after {waited:.2f} s; {len(topics)} topics on its graph"
    )


def test_the_server_joins_a_router_that_comes_up_after_it_and_starts_without_one() -> None:
    """No router at start: the server starts all the same (its world control answers); once a router
    comes up on the port, the server joins it and its samples flow through it."""
    port = free_port()
    with running_server("empty", "realtime", extra=("--ros-router", endpoint(port))) as sim:
        assert sim.state()["ok"]
        with ros_router(port) as at:
            waited, topics = _odom_through(at, sim.namespace)
        assert sim.alive()
    assert f"{sim.namespace}/odom" in topics, topics
    print(f"\nmeasured: odom through a router started after the server after {waited:.2f} s")
