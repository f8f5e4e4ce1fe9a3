"""`simbot remove`: take a model out of the running world through world control's `remove`.

    simbot remove NAME [--world NAME] [--timeout SECONDS] [--connect E] [--namespace NS]

Its systems stop, its keys leave the bus, a trolley it pulled goes free. Exit codes as
`simbot spawn`'s: 0 removed, 1 no world control answers, 2 a user's mistake (no such model).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from simbot.bus import Node

from .common import client_parser, run_client
from .spawn import DEFAULT_TIMEOUT_S, world_call
from .state import add_world_arguments


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot remove", "Take a model out of the running world (world control's remove).")
    parser.add_argument("name", help="the model's name in the world")
    add_world_arguments(parser, DEFAULT_TIMEOUT_S)
    return parser


def run(node: Node, name: str, world: str | None, timeout: float) -> int:
    """Asks `world` (None: the one on the bus) to remove model `name`, waiting `timeout` s; the exit code."""
    return world_call("simbot remove", node, world, timeout, "remove", {"name": name})


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot remove`."""
    return run_client(build_parser(), argv, lambda args, node, _: run(node, args.name, args.world, args.timeout))


if __name__ == "__main__":
    sys.exit(main())
