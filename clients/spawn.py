"""`simbot spawn`: add a model to the running world through world control's `create`.

    simbot spawn FILE [--name NAME] [--robot-namespace NS] [--pose X Y Z YAW] [--allow-renaming]
                      [--world NAME] [--timeout SECONDS] [--connect E] [--namespace NS]

FILE is an SDF (or URDF, xacro) model file that the server can read: its path goes to the server
made absolute, as Gazebo's `sdf_filename` does. `--robot-namespace` (every client's option: the
robot it follows) puts every key and frame of the model under NS (`tug_2/cmd_vel`,
`tug_2/base_link`); `--namespace` is the bus's namespace, as for every client. Prints the name the model got.

Exit codes: 0 the model is in the world; 1 no world control answers; 2 a user's mistake, the
server's refusal included (its one line, naming the field, on stderr).
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from simbot.bus import Node, ServiceError
from simbot.transform import yaw_quaternion

from .common import EXIT_USAGE, ClientError, client_parser, run_client
from .state import EXIT_NO_WORLD, NoWorld, add_world_arguments, choose_world

DEFAULT_TIMEOUT_S = 60.0
"""Loading a robot with its sensors takes a second or two; a loaded machine, more."""


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot spawn", "Add a model to the running world (world control's create).")
    parser.add_argument("file", help="the model's SDF, URDF or xacro file")
    parser.add_argument("--name", help="its name in the world (default: the file's model name)")
    parser.add_argument(
        "--pose", nargs=4, type=float, metavar=("X", "Y", "Z", "YAW"), help="where it appears (default: its own pose)"
    )
    parser.add_argument("--allow-renaming", action="store_true", help="a taken name becomes NAME_1, NAME_2, ...")
    add_world_arguments(parser, DEFAULT_TIMEOUT_S)
    return parser


def create_request(args: argparse.Namespace) -> dict[str, Any]:
    """The create request of the command line; ClientError for a pose that is not finite."""
    request: dict[str, Any] = {"sdf_filename": str(Path(args.file).absolute()), "allow_renaming": args.allow_renaming}
    if args.name is not None:
        request["name"] = args.name
    if args.robot_namespace:
        request["namespace"] = args.robot_namespace
    if args.pose is not None:
        if not all(math.isfinite(v) for v in args.pose):
            raise ClientError(f"--pose expects finite numbers, got {' '.join(map(str, args.pose))}")
        x, y, z, yaw = args.pose
        orientation = dict(zip("xyzw", yaw_quaternion(yaw), strict=True))
        request["pose"] = {"position": {"x": x, "y": y, "z": z}, "orientation": orientation}
    return request


def world_call(prog: str, node: Node, args: argparse.Namespace, service: str, request: dict[str, Any]) -> int:
    """Asks world control's `service`; prints the name it acted on, or the refusal; the exit code."""
    try:
        world = choose_world(node, args.world)
        reply = node.call(f"world/{world}/{service}", request, timeout=args.timeout)
    except NoWorld as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_NO_WORLD
    except (TimeoutError, ServiceError) as exc:
        print(f"{prog}: the world does not answer: {exc}", file=sys.stderr)
        return EXIT_NO_WORLD
    if reply.get("ok") is not True:
        print(f"{prog}: error: {reply.get('error', reply)}", file=sys.stderr)
        return EXIT_USAGE
    print(reply["name"], flush=True)
    return 0


def _run(args: argparse.Namespace, node: Node, stop: threading.Event) -> int:
    return world_call("simbot spawn", node, args, "create", create_request(args))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot spawn`."""
    return run_client(build_parser(), argv, _run)


if __name__ == "__main__":
    sys.exit(main())
