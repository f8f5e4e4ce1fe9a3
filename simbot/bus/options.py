"""The bus options every simbot program shares, and the Zenoh configuration they make.

Secure by default (SPEC §4): the server listens on `tcp/127.0.0.1:7448` only, clients connect
there and listen on nothing, multicast scouting is off. Anything wider is an explicit `--listen`
/ `--connect` or a Zenoh config file; what the config file sets is kept, what it leaves at
Zenoh's defaults gets ours. Without `--zenoh-config`, a ROS host's `ZENOH_SESSION_CONFIG_URI`
is that file, as it is for every rmw_zenoh node.

The ROS 2 graph (`simbot.bus.rmw`): 7447 is the port of `rmw_zenohd`, the router every rmw_zenoh
node connects to, so simbot leaves it free and its server connects there as a ROS node's session
does (`--ros-router`, default the endpoint `ZENOH_ROUTER_CONFIG_URI`'s router listens on, else
`tcp/127.0.0.1:7447`). With no router there, the server runs alone and joins one that starts
later; a ROS node without a router connects to the server's own endpoint. `ROS_DOMAIN_ID` and
`--ros-distro` say which domain and which distro's key format.

Roles map to Zenoh modes: the server is a `peer`, a client program is a Zenoh `client`. A client
session is brokered by the peer it connects to, so two client programs (the lidar merger and a
monitor) reach each other through the server; two non-listening *peers* would not (Zenoh 1.x
peers do not forward between other peers). A client waits up to `connect_timeout` seconds for
the server when it starts, then fails with one line; once connected it reconnects by itself.
Timestamping is on, which latched publishers (`zenoh.ext` advanced publishers) require.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import zenoh

from simbot.bus.keys import topic_key
from simbot.bus.rmw import DEFAULT_DISTRO, DISTROS, RosGraph, domain_from_env

logger = logging.getLogger(__name__)

Role = Literal["server", "client"]
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7448"
ROS_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where rmw_zenohd listens unless its configuration says otherwise."""
SESSION_CONFIG_ENV = "ZENOH_SESSION_CONFIG_URI"
ROUTER_CONFIG_ENV = "ZENOH_ROUTER_CONFIG_URI"
DEFAULT_CONNECT_TIMEOUT_S = 10.0
ROLE_MODES: dict[str, str] = {"server": "peer", "client": "client"}


class BusConfigError(ValueError):
    """A bad bus option or Zenoh config file; str() is the one line a CLI prints."""


def zenoh_reason(exc: BaseException) -> str:
    """Zenoh's error text on one line, without the Rust source location it appends."""
    text = " ".join(str(exc).split())
    return re.sub(r" at /\S+?\.rs:\d+\.?", "", text).strip()


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """Add --listen, --connect, --zenoh-config, --namespace and --connect-timeout to `parser`."""
    group = parser.add_argument_group("bus (Zenoh)")
    group.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"Zenoh endpoint to listen on, repeatable (server default: {DEFAULT_ENDPOINT}; clients: none)",
    )
    group.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"Zenoh endpoint to connect to, repeatable (client default: {DEFAULT_ENDPOINT})",
    )
    group.add_argument("--zenoh-config", type=Path, metavar="FILE", help="Zenoh JSON5 config file (kept as given)")
    group.add_argument("--namespace", default="", metavar="NS", help="prefix of every key, like a ROS namespace")
    group.add_argument(
        "--ros-distro",
        choices=DISTROS,
        default=DEFAULT_DISTRO,
        help=f"the ROS 2 distro whose rmw_zenoh key format to write (default {DEFAULT_DISTRO}; humble has no type hashes)",
    )
    group.add_argument(
        "--ros-router",
        metavar="ENDPOINT|none",
        help=f"server: the ROS 2 Zenoh router (rmw_zenohd) to join (default: where {ROUTER_CONFIG_ENV} says, else {ROS_ROUTER_ENDPOINT})",
    )
    group.add_argument(
        "--connect-timeout",
        type=float,
        default=DEFAULT_CONNECT_TIMEOUT_S,
        metavar="SECONDS",
        help=f"how long a client waits for the server at start (default {DEFAULT_CONNECT_TIMEOUT_S:g})",
    )


@dataclass(frozen=True)
class BusOptions:
    """Where to listen and connect, an optional Zenoh config file, and the key namespace."""

    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    config_file: Path | None = None
    namespace: str = ""
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S
    robot_namespace: str = ""
    """A client's robot within the bus's namespace (`tug_2`): where its relative topics resolve."""
    ros: RosGraph = field(default_factory=RosGraph)
    """The ROS 2 domain and distro of the keys and graph tokens."""
    ros_router: str | None = None
    """The server's ROS 2 router endpoint, `none` for none; None: the default (`ros_router_endpoint`)."""

    def __post_init__(self) -> None:
        for option, value in (("--namespace", self.namespace), ("--robot-namespace", self.robot_namespace)):
            if value.strip("/"):
                try:
                    topic_key("x", value)
                except ValueError as exc:
                    raise BusConfigError(f"{option} {value!r}: {exc}") from None
        if not self.connect_timeout >= 0:
            raise BusConfigError(f"--connect-timeout {self.connect_timeout}: must be a number of seconds ≥ 0")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> BusOptions:
        """The options parsed by a parser that `add_bus_arguments` set up."""
        config = getattr(args, "zenoh_config", None)
        try:
            ros = RosGraph(domain_from_env(), getattr(args, "ros_distro", DEFAULT_DISTRO))
        except ValueError as exc:
            raise BusConfigError(str(exc)) from None
        if config is None and os.environ.get(SESSION_CONFIG_ENV, "").strip():
            config = os.environ[SESSION_CONFIG_ENV].strip()
        return cls(
            listen=tuple(getattr(args, "listen", None) or ()),
            connect=tuple(getattr(args, "connect", None) or ()),
            config_file=Path(config) if config is not None else None,
            namespace=getattr(args, "namespace", "") or "",
            connect_timeout=float(getattr(args, "connect_timeout", DEFAULT_CONNECT_TIMEOUT_S)),
            robot_namespace=getattr(args, "robot_namespace", None) or "",
            ros=ros,
            ros_router=getattr(args, "ros_router", None),
        )


def helper_options(options: BusOptions) -> BusOptions:
    """The bus options of a process the server starts to publish for it (a render worker): a client
    of the server itself, at the endpoints it listens on (a unix socket first, a wildcard address as
    the loopback one),
    or, for a server that listens on none, where it connects; in no namespace of its own: the
    server names its keys in full."""
    config = zenoh_config(options, "server")
    listening = tuple(sorted((_local(e) for e in _endpoints(config, "listen/endpoints")), key=_not_a_socket))
    connect = listening or _endpoints(config, "connect/endpoints")
    return BusOptions(connect=connect, connect_timeout=options.connect_timeout, ros=options.ros)


def _not_a_socket(endpoint: str) -> bool:
    """Sorts a unix socket first: a worker has no certificate for a TLS endpoint, and a Zenoh client
    keeps retrying its first endpoint while that one's handshake fails."""
    return not endpoint.startswith("unixsock-stream/")


def ros_router_endpoint(options: BusOptions) -> str | None:
    """The router a server joins: `--ros-router`, else where ZENOH_ROUTER_CONFIG_URI's router listens
    (a wildcard address as the loopback one), else rmw_zenohd's default; None for `none`."""
    if options.ros_router is not None:
        return None if options.ros_router == "none" else options.ros_router
    path = os.environ.get(ROUTER_CONFIG_ENV, "").strip()
    if not path:
        return ROS_ROUTER_ENDPOINT
    listening = _endpoints(_load_file(Path(path)), "listen/endpoints")
    return _local(listening[0]) if listening else ROS_ROUTER_ENDPOINT


def _endpoints(config: zenoh.Config, key: str) -> tuple[str, ...]:
    """The endpoints at `key`: a list, or a map of them by Zenoh mode."""
    value = json.loads(config.get_json(key) or "[]")
    if isinstance(value, dict):
        value = value.get("peer", [])
    return tuple(str(endpoint) for endpoint in value)


def _local(endpoint: str) -> str:
    """A listening endpoint as a process on the same machine connects to it."""
    return endpoint.replace("/0.0.0.0:", "/127.0.0.1:").replace("/[::]:", "/[::1]:")


def _load_file(path: Path) -> zenoh.Config:
    if not path.is_file():
        raise BusConfigError(f"{path}: no such Zenoh config file")
    try:
        return zenoh.Config.from_file(str(path))
    except zenoh.ZError as exc:
        raise BusConfigError(f"{path}{_config_error(zenoh_reason(exc))}") from None


def _config_error(reason: str) -> str:
    """`:LINE:COL: invalid Zenoh config: WHAT` from the JSON5 parser's or the schema's message."""
    syntax = re.search(r"--> (\d+):(\d+) .*= (.+)$", reason)
    if syntax:
        return f":{syntax[1]}:{syntax[2]}: invalid Zenoh config: {syntax[3]}"
    schema = re.search(r'msg: "(.+)", location: Some\(Location \{ line: (\d+), column: (\d+)', reason)
    if schema:
        return f":{schema[2]}:{schema[3]}: invalid Zenoh config: {schema[1]}"
    return f": invalid Zenoh config: {reason}"


def _insert(config: zenoh.Config, key: str, value: Any, option: str) -> None:
    try:
        config.insert_json5(key, json.dumps(value))
    except zenoh.ZError as exc:
        raise BusConfigError(f"{option}: {zenoh_reason(exc)}") from None


def _check_endpoints(option: str, endpoints: tuple[str, ...]) -> None:
    """Each endpoint alone, so that the error names the bad one."""
    scratch = zenoh.Config()
    for endpoint in endpoints:
        try:
            scratch.insert_json5("connect/endpoints", json.dumps([endpoint]))
        except zenoh.ZError:
            raise BusConfigError(
                f"{option} {endpoint!r}: not a Zenoh endpoint (expected PROTOCOL/ADDRESS, e.g. {DEFAULT_ENDPOINT})"
            ) from None


def _default_connect(options: BusOptions, role: Role) -> list[str]:
    """A client connects to the server; the server to the ROS 2 router, if any (retried in the background)."""
    if role == "client":
        return [DEFAULT_ENDPOINT]
    router = ros_router_endpoint(options)
    if router is not None:
        _check_endpoints("--ros-router", (router,))
    return [router] if router is not None and router not in options.listen else []


def zenoh_config(options: BusOptions, role: Role) -> zenoh.Config:
    """The Zenoh configuration of a server or client session with `options` applied."""
    if role not in ROLE_MODES:
        raise ValueError(f"role must be 'server' or 'client', not {role!r}")
    _check_endpoints("--listen", options.listen)
    _check_endpoints("--connect", options.connect)
    config = _load_file(options.config_file) if options.config_file is not None else zenoh.Config()
    defaults = zenoh.Config()

    def unset(key: str) -> bool:
        """True when the config file left `key` at Zenoh's default."""
        return options.config_file is None or config.get_json(key) == defaults.get_json(key)

    source = str(options.config_file) if options.config_file is not None else "defaults"
    if unset("mode"):
        _insert(config, "mode", ROLE_MODES[role], source)
    if unset("scouting/multicast/enabled"):
        _insert(config, "scouting/multicast/enabled", False, source)
    if unset("timestamping/enabled"):
        _insert(config, "timestamping/enabled", True, source)
    if options.listen:
        _insert(config, "listen/endpoints", list(options.listen), "--listen")
    elif unset("listen/endpoints"):
        _insert(config, "listen/endpoints", [DEFAULT_ENDPOINT] if role == "server" else [], source)
    if options.connect:
        _insert(config, "connect/endpoints", list(options.connect), "--connect")
    elif unset("connect/endpoints"):
        _insert(config, "connect/endpoints", _default_connect(options, role), source)
    if role == "server" and unset("scouting/delay"):
        _insert(config, "scouting/delay", 0, source)  # a router that is not there must not hold the start
    if role == "client" and unset("connect/timeout_ms"):
        _insert(config, "connect/timeout_ms", round(options.connect_timeout * 1000), "--connect-timeout")
    logger.debug(
        "zenoh %s config: mode %s, listen %s, connect %s",
        role,
        config.get_json("mode"),
        config.get_json("listen/endpoints"),
        config.get_json("connect/endpoints"),
    )
    return config
