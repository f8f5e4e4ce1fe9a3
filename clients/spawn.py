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
from collections.abc import Sequence
from dataclasses import dataclass
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


@dataclass(frozen=True)
class Spawn:
    """What `simbot spawn` asks for: the model's file, and optionally its name, namespace and pose."""

    file: Path
    name: str | None = None
    robot_namespace: str = ""
    pose: Sequence[float] | None = None
    """x, y, z (m) and yaw (rad) in the world."""
    allow_renaming: bool = False


def create_request(spawn: Spawn) -> dict[str, Any]:
    """World control's create request for `spawn`; ClientError for a pose that is not finite."""
    request: dict[str, Any] = {"sdf_filename": str(spawn.file.absolute()), "allow_renaming": spawn.allow_renaming}
    if spawn.name is not None:
        request["name"] = spawn.name
    if spawn.robot_namespace:
        request["namespace"] = spawn.robot_namespace
    if spawn.pose is not None:
        if not all(math.isfinite(v) for v in spawn.pose):
            raise ClientError(f"--pose expects finite numbers, got {' '.join(map(str, spawn.pose))}")
        x, y, z, yaw = spawn.pose
        orientation = dict(zip("xyzw", yaw_quaternion(yaw), strict=True))
        request["pose"] = {"position": {"x": x, "y": y, "z": z}, "orientation": orientation}
    return request


def world_call(prog: str, node: Node, world: str | None, timeout: float, service: str, request: dict[str, Any]) -> int:
    """Asks world control's `service` of `world` (None: the one on the bus), waiting `timeout` s; prints
    the name it acted on, or the refusal; the exit code."""
    try:
        chosen = choose_world(node, world)
        reply = node.call(f"world/{chosen}/{service}", request, timeout=timeout)
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


def run(node: Node, spawn: Spawn, world: str | None, timeout: float) -> int:
    """Asks `world` (None: the one on the bus) to create `spawn`, waiting `timeout` s; the exit code."""
    return world_call("simbot spawn", node, world, timeout, "create", create_request(spawn))


def _spawn(args: argparse.Namespace) -> Spawn:
    return Spawn(Path(args.file), args.name, args.robot_namespace, args.pose, args.allow_renaming)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot spawn`."""
    return run_client(build_parser(), argv, lambda args, node, _: run(node, _spawn(args), args.world, args.timeout))


if __name__ == "__main__":
    sys.exit(main())
