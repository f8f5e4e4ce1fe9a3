"""The zones of `simbot launch --zones N` (or `--zone NAME:XMIN:XMAX` repeated): what to start for them.

The `--robots N` fleet that `--server-args` asks for is laid out as the zone servers will lay it
(simbot.description.fleet): in `--columns` columns as given, else one column per zone, so that
bands of x can split it. `--zones N`'s boundaries lie between columns, each zone holding about as
many robots; `--zone`'s bands must hold every robot, and no two may overlap. Each zone is a
`simbot-server --zone NAME:XMIN:XMAX` on a free loopback port, connected to launch's router (a
Zenoh session in router mode, in launch's own process), which listens where `--listen` says, so
the clients connect there as to one server; `simbot handover 'tug_*'` then watches the fleet.
"""

from __future__ import annotations

import argparse
import json
import math
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import zenoh

from simbot.arguments import whole
from simbot.bus import BusOptions, zenoh_config
from simbot.description.fleet import DEFAULT_SPAWN, MAX_FLEET, Spot, Zone, check_zones, fleet, split
from simbot.description.resources import asset

ROBOTS = "tug_*"
"""The fleet's robots, as the handover matches them (`--robots N` names them tug_1..tug_N)."""
LOAD_PER_ROBOT_S = 0.5
"""Seconds more to start for each robot of the fleet: two zones of a hundred full tugs each loaded
in 15 s here, side by side; a loaded machine takes longer."""


class ZoneError(Exception):
    """A mistake in the zones or the fleet they split; str() is the one line printed."""


@dataclass(frozen=True)
class ServerPlan:
    """A server to start: its name (`server`, or its zone's), its command, and the bus options
    that reach its world control (in a zone, under the zone's name)."""

    name: str
    command: list[str]
    bus: BusOptions
    about: str = ""
    """What launch says of it before it starts (a zone: its band and robots)."""


@dataclass(frozen=True)
class ZonePlan:
    """The zone servers, the router that joins them, the handover's command (less `--world`), and
    how long to wait for them all."""

    servers: list[ServerPlan]
    router: zenoh.Config
    handover: list[str]
    startup_timeout_s: float


@dataclass(frozen=True)
class Fleet:
    """The `--robots N` fleet of --server-args as the zone servers lay it out, and its model file."""

    spots: list[Spot]
    columns: int
    """`--columns` as given, else one column per zone."""
    given_columns: bool
    robot: Path


def read_fleet(words: Sequence[str], zones: int) -> Fleet:
    """The fleet the server options `words` ask for; ZoneError when they ask for none."""
    parser = argparse.ArgumentParser(add_help=False, allow_abbrev=False, exit_on_error=False)
    parser.add_argument("--robots", type=whole(1, MAX_FLEET), default=0)
    parser.add_argument("--columns", type=whole(1))
    parser.add_argument("--spawn", nargs=4, type=float, default=DEFAULT_SPAWN)
    parser.add_argument("--robot")
    try:
        known, _ = parser.parse_known_args(words)
    except argparse.ArgumentError as exc:
        raise ZoneError(f"--server-args: {exc}") from None
    if not known.robots or known.robot == "none":
        raise ZoneError('--zones: zones split a fleet: give one, --server-args="--robots N ..."')
    if not all(math.isfinite(v) for v in known.spawn):
        raise ZoneError(f"--server-args: --spawn expects finite numbers, got {' '.join(map(str, known.spawn))}")
    columns = known.columns or zones
    robot = Path(known.robot) if known.robot else asset("urdf/flexley_tug.sdf")
    return Fleet(fleet(known.spawn, known.robots, columns), columns, known.columns is not None, robot)


def zones_of(args: argparse.Namespace, spots: Sequence[Spot]) -> list[Zone]:
    """`--zone`'s bands, checked against where the robots stand, or `--zones N`'s from their x."""
    if args.zone and args.zones:
        raise ZoneError("--zones and --zone: give one or the other")
    if args.zone:
        try:
            check_zones(args.zone, spots)
        except ValueError as exc:
            raise ZoneError(f"--zone: {exc}") from None
        return list(args.zone)
    try:
        return split(spots, [f"zone_{k}" for k in range(1, args.zones + 1)])
    except ValueError as exc:
        raise ZoneError(f"--zones {args.zones}: {exc}") from None


def zone_plan(
    args: argparse.Namespace, server: list[str], endpoints: Sequence[str], handover: list[str], connect_try_s: float
) -> ZonePlan:
    """A server per zone (`server` is the command each runs, --server-args included), each on a free
    loopback port and connected to the router at `endpoints`, where the clients connect too."""
    fleet = read_fleet(server, args.zones or len(args.zone))
    zones = zones_of(args, fleet.spots)
    router = zenoh_config(
        BusOptions(tuple(args.listen), tuple(args.connect), args.zenoh_config, ros_router="none"), "server"
    )
    router.insert_json5("mode", json.dumps("router"))
    server = [*server, *([] if fleet.given_columns else ["--columns", str(fleet.columns)])]
    to_router = [word for endpoint in endpoints for word in ("--connect", endpoint)]
    servers = []
    for each in zones:
        command = [*server, "--zone", str(each), "--listen", free_endpoint(), *to_router]
        namespace = "/".join(part for part in (args.namespace.strip("/"), each.name) if part)
        bus = BusOptions(connect=tuple(endpoints), namespace=namespace, connect_timeout=connect_try_s)
        held = sum(each.holds(spot.x) for spot in fleet.spots)
        servers.append(
            ServerPlan(each.name, command, bus, f"zone {each} holds {held} of the {len(fleet.spots)} robots")
        )
    handover = [*handover, ROBOTS, "--file", str(fleet.robot), *(f"--zone={each}" for each in zones)]
    return ZonePlan(servers, router, handover, LOAD_PER_ROBOT_S * len(fleet.spots))


def free_endpoint() -> str:
    """A loopback TCP endpoint on a port free now (the server binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"
