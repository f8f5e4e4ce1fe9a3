"""Beyond one machine: two servers, each its own world under its own namespace, joined by one Zenoh
router into one key space (issue 17, item 5), all on 127.0.0.1.

The router is `docker/zenoh_router.py`, the program the fleet's compose file runs (a Zenoh session
in router mode: the eclipse-zenoh package ships no `zenohd`), in a subprocess, configured by
`docker/zenoh-router.json5` with only its endpoints replaced:
it listens on a fresh port and connects to both servers' ports. A client that connects to the
router alone receives both servers' `clock` and `odom` and calls both worlds' control.

Having had a router connected does not slow a server's exit: SIGTERM to exit took 0.2–0.6 s here
(0.6–1.6 s under two busy loops on this 2-core machine), of which the server's own closing
(systems, physics, 34 undeclares and the Zenoh session) is 10–25 ms and the rest is the Python
interpreter's finalisation of its modules (about 0.13 s unloaded); so the 2 s of every server
test holds.
"""

from __future__ import annotations

import json
import time

import yaml  # PyYAML, which xacro requires
import zenoh
from bus_helpers import free_port
from conftest import REPO
from server_helpers import ROUTER_CONFIG, Collector, SimServer, keyed_payload, raw_samples, router, running_server

from simbot.bus import BusOptions, Node


def _client(at: str) -> zenoh.Session:
    """A plain Zenoh client of the router only, multicast scouting off."""
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([at]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def _step_until(servers: list[SimServer], seen: Collector[tuple[str, bytes]], keys: set[str]) -> None:
    """Lockstep: both servers step in small chunks until every key has come through the router."""
    deadline = time.monotonic() + 20.0
    while not keys <= {key for key, _ in seen.messages()}:
        missing = keys - {key for key, _ in seen.messages()}
        assert time.monotonic() < deadline, f"nothing through the router on {sorted(missing)}"
        for server in servers:
            server.step(20)
        time.sleep(0.01)


def test_a_client_of_the_router_sees_both_servers() -> None:
    """clock and odom of both namespaces arrive through the router, and both worlds answer their state."""
    with running_server() as site_a, running_server() as site_b:
        servers = [site_a, site_b]
        assert site_a.port != site_b.port and site_a.namespace != site_b.namespace
        with router(free_port(), servers) as at, _client(at) as session:
            keys = {f"{s.namespace}/{topic}" for s in servers for topic in ("clock", "odom")}
            with raw_samples(session, "**", keyed_payload) as seen:
                _step_until(servers, seen, keys)
            with Node(BusOptions(connect=(at,)), "client") as node:
                for server in servers:
                    state = node.call(f"{server.namespace}/world/{server.world}/state", {}, timeout=5.0)
                    assert state["ok"] and state["sim_time"] > 0, state
        exits = [server.stop() for server in (site_b, site_a)]  # each within what every server test allows
    print(f"\nrouted servers exited in {', '.join(f'{s:.2f}' for s in exits)} s of SIGTERM")


def test_the_fleet_compose_file_joins_its_servers_through_the_router_config() -> None:
    """docker/compose.fleet.yaml: one namespace per server, each health check asking its own, and the
    router's config (the file the test above runs) connecting to exactly those servers."""
    compose = yaml.safe_load((REPO / "docker" / "compose.fleet.yaml").read_text())
    services = compose["services"]
    sites = {name: s for name, s in services.items() if s["command"][0] == "simbot-server"}
    assert len(sites) == 2
    for name, site in sites.items():
        command, health = site["command"], site["healthcheck"]["test"]
        assert command[command.index("--namespace") + 1] == name == health[health.index("--namespace") + 1]
    assert "./zenoh-router.json5:/etc/zenoh/router.json5:ro" in services["router"]["volumes"]
    config = zenoh.Config.from_file(str(ROUTER_CONFIG))
    assert json.loads(config.get_json("connect/endpoints")) == [f"tcp/{name}:7448" for name in sites]
    assert json.loads(config.get_json("mode")) == "router"
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
