"""`simbot`: the command line. Each subcommand is a small function; user mistakes exit 2
with one line on stderr, never a traceback.

The client programs (`clients/`) are subcommands too: `simbot teleop ARGS` runs
`simbot.clients.teleop.main(ARGS)`, imported only when asked for, so `simbot describe` never loads them.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from simbot.description import DescriptionError, load_description, load_model, model_to_urdf
from simbot.description.summary import left_out_table, summarize
from simbot.sim.loop.sdf_systems import left_out_of

EXIT_USAGE = 2

CLIENTS: dict[str, str] = {
    "teleop": "drive the robot from the keyboard, stopping short of obstacles",
    "merger": "merge the two lidars into one 360° scan in base_link",
    "stitcher": "stitch the six cameras into one panorama",
    "dock": "attach and detach the trolley from the keyboard",
    "topics": "list the live keys with their type, rate and bandwidth",
    "echo": "print the decoded messages of a key",
    "monitor": "a live table of every sensor",
    "snapshot": "write the panorama and a top-down map of the merged scan as PNGs",
    "launch": "start the server and chosen clients; Ctrl-C ends them all",
    "state": "print the world's state from its world control; exit 1 when it does not answer (the container's health check)",
    "spawn": "add a model to the running world (world control's create), in a namespace of its own if asked",
    "remove": "take a model out of the running world (world control's remove)",
    "handover": "move robots between zone servers (one world split by x) as they cross their boundaries",
    "record": "record keys into a rosbag2 bag in MCAP storage; Ctrl-C closes it",
    "play": "publish a recorded bag back onto the bus at its recorded rate",
    "dataset": "write synchronised camera frames (RGB, depth, label maps, boxes) with intrinsics and poses as a dataset",
    "foxglove": "serve the live bus to the Foxglove app over its WebSocket protocol (pip install 'simbot[foxglove]')",
    "ros2": "carry the bus to ROS 2 nodes (DDS) and back through rclpy, bytes unchanged (pip install 'simbot[ros2]')",
}
"""Client subcommands: each is the module `simbot.clients.<name>`, whose `main(argv)` takes the rest of the line."""

COMMANDS: dict[str, tuple[str, str]] = {
    "experiment": (
        "simbot.gym.experiment",
        "run episodes of a policy in a simbot Gymnasium environment across Ray actors, into a CSV "
        "(pip install 'simbot[gym,ray]')",
    ),
    "map": ("simbot.mapping.command", "write a world's ground-truth occupancy map for Nav2 (map.pgm, map.yaml)"),
}
"""Other subcommands run the same way: name → (the module whose `main(argv)` takes the rest of the
line, its summary); imported only when asked for, as the clients are."""


def _sdf2urdf(args: argparse.Namespace) -> int:
    model = load_model(args.input)
    if args.output is None:
        sys.stdout.write(model_to_urdf(model))
        return 0
    out = Path(args.output)
    try:
        out.write_text(model_to_urdf(model, out.parent))
    except OSError as exc:
        raise DescriptionError(out, f"cannot write: {exc.strerror or exc}") from None
    print(f"wrote {out}: {len(model.links)} links, {len(model.joints)} joints", file=sys.stderr)
    return 0


def _describe(args: argparse.Namespace) -> int:
    """The file's tables, then the systems a server would leave out of its world and why: checked
    by the server's own code (`simbot.sim.loop.sdf_systems.left_out_of`), with no server running."""
    description = load_description(args.file)
    print(summarize(description))
    print()
    print(left_out_table([(entry.name, entry.kind, entry.reason) for entry in left_out_of(description)]))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="simbot", description="simbot: a headless simulator of the ABB Flexley Tug")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    convert = commands.add_parser("sdf2urdf", help="convert an SDF model to URDF")
    convert.add_argument("input", help="SDF model file")
    convert.add_argument("-o", "--output", help="URDF file to write (default: standard output)")
    convert.set_defaults(run=_sdf2urdf)
    describe = commands.add_parser(
        "describe",
        help="print the links, joints, sensors and plugins of an SDF, URDF or xacro file, and those a server would "
        "leave out for bad parameters",
    )
    describe.add_argument("file", help="SDF world or model, URDF, or xacro file")
    describe.set_defaults(run=_describe)
    for name, summary in CLIENTS.items():
        commands.add_parser(name, help=summary, add_help=False)
    for name, (_module, summary) in COMMANDS.items():
        commands.add_parser(name, help=summary, add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `simbot` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in CLIENTS:
        client: Callable[[Sequence[str]], int] = importlib.import_module(f"simbot.clients.{argv[0]}").main
        return client(argv[1:])
    if argv and argv[0] in COMMANDS:
        try:
            command: Callable[[Sequence[str]], int] = importlib.import_module(COMMANDS[argv[0]][0]).main
        except ImportError as exc:  # an optional extra not installed: say which, not a traceback
            print(f"simbot {argv[0]}: needs {exc.name or exc}: {COMMANDS[argv[0]][1]}", file=sys.stderr)
            return 2
        return command(argv[1:])
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    run: Callable[[argparse.Namespace], int] = args.run
    try:
        return run(args)
    except DescriptionError as exc:
        print(f"simbot {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
