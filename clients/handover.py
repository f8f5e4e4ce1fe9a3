"""`simbot handover`: one warehouse split into zones, a server each, and robots moved across as they cross.

    simbot handover ROBOT [ROBOT ...] --zone NS:XMIN:XMAX --zone NS:XMIN:XMAX [...] [--file SDF]
                    [--every SECONDS] [--once] [--world NAME] [--timeout SECONDS] [--connect E] [--namespace NS]

Each zone is a server whose world control is under NS (its bus namespace, the servers joined by
Zenoh routers, see docs/fleets.md; or the `--zone` name of a `simbot-server --zone`, as
`simbot launch --zones` starts them) and owns the band XMIN ≤ x < XMAX of a world frame the zones
share. Each ROBOT is a model name or a shell pattern (`'tug_*'`: every model whose name matches),
so one client watches a whole fleet. Every `--every` seconds it reads each zone's world state
once; when a robot stands in one zone's world outside that zone's band and inside another's, the
client creates it in the other (world control's `create`: FILE, the same name, the robot
namespace of its name, its pose) and then removes it from the first (`remove`). Created first, so
a refused create leaves it where it was. What crosses is its pose; its drive starts from rest
there, and follows the commands on its `cmd_vel` in the zone that now holds it (one line on
stdout per handover says where it went). FILE must be readable by every zone's server (the same
path on each host).

A zone whose world control stops answering is left out, with one line on stderr, until it
answers again; the others are watched on.

Exit codes: 0 stopped (or, with `--once`, after one handover); 1 no zone's world control answers
(with `--once`: one zone's does not); 2 a user's mistake (a bad zone, a refused create or remove:
its one line on stderr).
"""

from __future__ import annotations

import argparse
import fnmatch
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simbot.arguments import number
from simbot.bus import Node, ServiceError
from simbot.description.fleet import Zone, zone
from simbot.description.resources import asset

from .common import ClientError, client_parser, run_client
from .state import EXIT_NO_WORLD

DEFAULT_TIMEOUT_S = 60.0
"""Loading a robot with its sensors takes a second or two; a loaded machine, more."""


class NoAnswer(Exception):
    """A zone's world control did not answer."""


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot handover", "Move robots between zone servers as they cross their boundaries.")
    parser.add_argument(
        "robots",
        nargs="+",
        metavar="ROBOT",
        help="a robot's model name (and robot namespace) in the zones' worlds, or a shell pattern such as 'tug_*'",
    )
    parser.add_argument("--zone", type=zone, action="append", required=True, metavar="NS:XMIN:XMAX")
    parser.add_argument("--file", type=Path, default=asset("urdf/flexley_tug.sdf"), help="the robot's model file")
    parser.add_argument("--world", default="warehouse", metavar="NAME", help="the zones' world (default warehouse)")
    parser.add_argument("--every", type=number(float), default=0.2, metavar="SECONDS", help="how often to look")
    parser.add_argument("--once", action="store_true", help="exit after the first handover")
    parser.add_argument("--timeout", type=number(float), default=DEFAULT_TIMEOUT_S, metavar="SECONDS")
    return parser


@dataclass(frozen=True)
class Handover:
    """What `simbot handover` watches and how: the robots (names or shell patterns), the zones, the
    robot's model file, the zones' world, how often it looks, and how long a call may take."""

    robots: Sequence[str]
    zones: Sequence[Zone]
    file: Path
    world: str = "warehouse"
    every_s: float = 0.2
    once: bool = False
    """Exit after the first handover."""
    timeout_s: float = DEFAULT_TIMEOUT_S


def _call(node: Node, handover: Handover, zone: Zone, service: str, request: dict[str, Any]) -> dict[str, Any]:
    """One world-control call in `zone`; NoAnswer when it does not answer, ClientError when it refuses."""
    try:
        reply = node.call(f"{zone.name}/world/{handover.world}/{service}", request, timeout=handover.timeout_s)
    except (TimeoutError, ServiceError) as exc:
        raise NoAnswer(f"zone {zone.name}: the world does not answer: {exc}") from None
    if reply.get("ok") is not True:
        raise ClientError(f"zone {zone.name}: {service} refused: {reply.get('error', reply)}")
    return reply


def wanted(handover: Handover, name: str) -> bool:
    """Whether model `name` is one of the robots to watch (a name or a pattern of the command line)."""
    return any(fnmatch.fnmatchcase(name, pattern) for pattern in handover.robots)


class Watch:
    """The zones and what their worlds hold at each look; which zones stopped answering."""

    def __init__(self, node: Node, handover: Handover) -> None:
        self.node, self.handover = node, handover
        self.silent: set[Zone] = set()

    def look(self) -> list[tuple[str, Zone, Zone, dict[str, Any]]]:
        """Each watched robot that stands outside the band of the zone holding it and inside
        another's: (name, its zone, the other, its state). A robot in two zones (mid-handover, or
        a create whose remove was refused) counts in the first. NoAnswer when no zone answers."""
        seen: dict[str, tuple[Zone, dict[str, Any]]] = {}
        for each in self.handover.zones:
            models = self._models(each)
            for name, state in (models or {}).items():
                if wanted(self.handover, name):
                    seen.setdefault(name, (each, state))
        if len(self.silent) == len(self.handover.zones):
            raise NoAnswer("no zone's world answers")
        moves = []
        for name, (source, state) in seen.items():
            x = state["position"][0]
            if x is None or source.holds(x):  # null: a body that left the world
                continue
            target = next((z for z in self.handover.zones if z.holds(x) and z not in self.silent), None)
            if target is not None:
                moves.append((name, source, target, state))
        return moves

    def _models(self, zone: Zone) -> dict[str, Any] | None:
        """The models of `zone`'s world, or None (said once) while it does not answer."""
        try:
            models: dict[str, Any] = _call(self.node, self.handover, zone, "state", {})["models"]
        except NoAnswer as exc:
            if self.handover.once:
                raise
            if zone not in self.silent:
                print(f"simbot handover: {exc}; watching the other zones", file=sys.stderr, flush=True)
            self.silent.add(zone)
            return None
        if zone in self.silent:
            print(f"simbot handover: zone {zone.name} answers again", file=sys.stderr, flush=True)
            self.silent.discard(zone)
        return models


def hand_over(node: Node, handover: Handover, robot: str, source: Zone, target: Zone, state: dict[str, Any]) -> None:
    """Created in `target` at the pose it has in `source`, then removed from `source`."""
    (x, y, z), (qx, qy, qz, qw) = state["position"], state["orientation"]
    pose = {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}
    request = {"sdf_filename": str(handover.file.absolute()), "name": robot, "namespace": robot, "pose": pose}
    _call(node, handover, target, "create", request)
    _call(node, handover, source, "remove", {"name": robot})
    print(f"{robot}: {source.name} → {target.name} at x {x:.3f} y {y:.3f}", flush=True)


def run(node: Node, stop: threading.Event, handover: Handover) -> int:
    """Hands the robots over between the zones until `stop` (or after the first, `once`); the exit code."""
    watch = Watch(node, handover)
    try:
        while not stop.is_set():
            for robot, source, target, state in watch.look():
                try:
                    hand_over(node, handover, robot, source, target, state)
                except NoAnswer as exc:
                    if handover.once:
                        raise
                    print(f"simbot handover: {robot} stays in {source.name}: {exc}", file=sys.stderr, flush=True)
                    continue
                if handover.once:
                    return 0
            stop.wait(handover.every_s)
    except NoAnswer as exc:
        print(f"simbot handover: {exc}", file=sys.stderr)
        return EXIT_NO_WORLD
    return 0


def _handover_of(args: argparse.Namespace) -> Handover:
    return Handover(args.robots, args.zone, args.file, args.world, args.every, args.once, args.timeout)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot handover`."""
    return run_client(build_parser(), argv, lambda args, node, stop: run(node, stop, _handover_of(args)))


if __name__ == "__main__":
    sys.exit(main())
