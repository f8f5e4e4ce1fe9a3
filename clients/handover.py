"""`simbot handover`: one warehouse split into zones, a server each, and a robot moved across as it crosses.

    simbot handover ROBOT --zone NS:XMIN:XMAX --zone NS:XMIN:XMAX [...] [--file SDF] [--every SECONDS]
                    [--once] [--world NAME] [--timeout SECONDS] [--connect E] [--namespace NS]

Each zone is a server under its own bus namespace NS (the servers joined by Zenoh routers: see
"Beyond one machine" in the README) and owns the band XMIN ≤ x < XMAX of a world frame the zones
share. Every `--every` seconds the client finds ROBOT in the zones' world states; when it stands
in one zone's world outside that zone's band and inside another's, the client creates it in the
other (world control's `create`: FILE, the same name, the robot namespace ROBOT, its pose) and
then removes it from the first (`remove`). Created first, so a refused create leaves it where it
was. What crosses is its pose; its drive starts from rest there, so whatever commands it sends to
`<next zone>/ROBOT/cmd_vel` from then on (one line on stdout per handover says where it went).
FILE must be readable by every zone's server (the same path on each host).

Exit codes: 0 stopped (or, with `--once`, after one handover); 1 a zone's world control does not
answer; 2 a user's mistake (a bad zone, a refused create or remove: its one line on stderr).
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simbot.arguments import number
from simbot.bus import Node, ServiceError
from simbot.description.resources import asset

from .common import ClientError, client_parser, run_client
from .state import EXIT_NO_WORLD

DEFAULT_TIMEOUT_S = 60.0
"""Loading a robot with its sensors takes a second or two; a loaded machine, more."""


@dataclass(frozen=True)
class Zone:
    """A server's namespace and the band of x it owns."""

    namespace: str
    x_min: float
    x_max: float

    def holds(self, x: float) -> bool:
        return self.x_min <= x < self.x_max


def zone(text: str) -> Zone:
    """An argparse type: `NS:XMIN:XMAX` (either bound may be -inf or inf)."""
    namespace, _, bounds = text.partition(":")
    low, _, high = bounds.partition(":")
    try:
        x_min, x_max = float(low), float(high)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NS:XMIN:XMAX such as site_a:-inf:20, got {text!r}") from None
    if not namespace.strip("/") or math.isnan(x_min) or math.isnan(x_max) or x_min >= x_max:
        raise argparse.ArgumentTypeError(f"expected NS:XMIN:XMAX with a namespace and XMIN < XMAX, got {text!r}")
    return Zone(namespace.strip("/"), x_min, x_max)


class NoAnswer(Exception):
    """A zone's world control did not answer."""


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot handover", "Move a robot between zone servers as it crosses their boundary.")
    parser.add_argument("robot", help="the robot's model name (and robot namespace) in the zones' worlds")
    parser.add_argument("--zone", type=zone, action="append", required=True, metavar="NS:XMIN:XMAX")
    parser.add_argument("--file", type=Path, default=asset("urdf/flexley_tug.sdf"), help="the robot's model file")
    parser.add_argument("--world", default="warehouse", metavar="NAME", help="the zones' world (default warehouse)")
    parser.add_argument("--every", type=number(float), default=0.2, metavar="SECONDS", help="how often to look")
    parser.add_argument("--once", action="store_true", help="exit after the first handover")
    parser.add_argument("--timeout", type=number(float), default=DEFAULT_TIMEOUT_S, metavar="SECONDS")
    return parser


def _call(node: Node, args: argparse.Namespace, zone: Zone, service: str, request: dict[str, Any]) -> dict[str, Any]:
    """One world-control call in `zone`; NoAnswer when it does not answer, ClientError when it refuses."""
    try:
        reply = node.call(f"{zone.namespace}/world/{args.world}/{service}", request, timeout=args.timeout)
    except (TimeoutError, ServiceError) as exc:
        raise NoAnswer(f"zone {zone.namespace}: the world does not answer: {exc}") from None
    if reply.get("ok") is not True:
        raise ClientError(f"zone {zone.namespace}: {service} refused: {reply.get('error', reply)}")
    return reply


def find(node: Node, args: argparse.Namespace) -> tuple[Zone, dict[str, Any]] | None:
    """The zone whose world holds the robot, and its state there; None when none does (mid-handover)."""
    for each in args.zone:
        models = _call(node, args, each, "state", {})["models"]
        if args.robot in models:
            return each, models[args.robot]
    return None


def hand_over(node: Node, args: argparse.Namespace, source: Zone, target: Zone, state: dict[str, Any]) -> None:
    """Created in `target` at the pose it has in `source`, then removed from `source`."""
    (x, y, z), (qx, qy, qz, qw) = state["position"], state["orientation"]
    pose = {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}
    request = {"sdf_filename": str(args.file.absolute()), "name": args.robot, "namespace": args.robot, "pose": pose}
    _call(node, args, target, "create", request)
    _call(node, args, source, "remove", {"name": args.robot})
    print(f"{args.robot}: {source.namespace} → {target.namespace} at x {x:.3f} y {y:.3f}", flush=True)


def _run(args: argparse.Namespace, node: Node, stop: threading.Event) -> int:
    try:
        while not stop.is_set():
            found = find(node, args)
            if found is not None:
                source, state = found
                x = state["position"][0]
                target = next((z for z in args.zone if z.holds(x)), None)
                if not source.holds(x) and target is not None:
                    hand_over(node, args, source, target, state)
                    if args.once:
                        return 0
            stop.wait(args.every)
    except NoAnswer as exc:
        print(f"simbot handover: {exc}", file=sys.stderr)
        return EXIT_NO_WORLD
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot handover`."""
    return run_client(build_parser(), argv, _run)


if __name__ == "__main__":
    sys.exit(main())
