"""`simbot map`: a world's ground-truth map as Nav2's map_server files (docs/map.md).

    simbot map --world NAME|PATH [--add NAME|PATH ...] [--randomise SEED[:PROFILE]] [--resolution M]
               [--height Z | --band ZMIN:ZMAX] [--people] -o DIR

The world and its additions are found and loaded as simbot-server finds and loads them (its
`world_path`, `addition_path`, `with_additions`), so the map is of the world a server would run;
with `--randomise`, of the variant a server started with the same option runs (its clutter, its
trolley where the seed put it: docs/variation.md).
A mistake (a resolution that is not a positive number, a band whose low end is above its high end
or that is not two numbers, a world file that is not there or does not read) is one line naming
the option or the file, and exit code 2.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from simbot.arguments import number
from simbot.description import DescriptionError, load_world
from simbot.description.additions import addition_path, with_additions, world_path
from simbot.mapping.nav2_map import write_map
from simbot.mapping.occupancy import LIDAR_HEIGHT, RESOLUTION, world_map
from simbot.mapping.shapes import Band
from simbot.variation import profile_beside, read_profile, seed_option, vary

PROG = "simbot map"
EXIT_USAGE = 2
log = logging.getLogger(__name__)


class _Parser(argparse.ArgumentParser):
    """argparse, but a mistake is one line (no usage block), as every other bad input here."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _height(text: str) -> Band:
    try:
        return Band.at(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a height in metres, got {text!r}") from None


def _band(text: str) -> Band:
    low, colon, high = text.partition(":")
    try:
        if not colon:
            raise ValueError
        return Band(float(low), float(high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ZMIN:ZMAX, two heights with ZMIN <= ZMAX, got {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="write a world's ground-truth occupancy map as map.pgm and map.yaml")
    parser.add_argument(
        "--world", default="warehouse", help="world file, or a built-in world: warehouse (default), empty"
    )
    parser.add_argument(
        "--add", action="append", default=[], metavar="NAME|PATH", help="another SDF file's models, as simbot-server's"
    )
    parser.add_argument(
        "--resolution", type=number(float, unit="m"), default=RESOLUTION, help=f"metres per cell (default {RESOLUTION})"
    )
    cut = parser.add_mutually_exclusive_group()
    cut.add_argument(
        "--height",
        dest="band",
        type=_height,
        metavar="Z",
        help=f"cut at this height, metres (default {LIDAR_HEIGHT}: the tug's lidars)",
    )
    cut.add_argument("--band", dest="band", type=_band, metavar="ZMIN:ZMAX", help="everything between two heights")
    parser.add_argument(
        "--randomise",
        type=seed_option,
        metavar="SEED[:PROFILE]",
        help="the world SEED draws from a variation profile (default: the world's own), as simbot-server --randomise",
    )
    parser.add_argument("--people", action="store_true", help="the actors' collision proxies at time 0 too")
    parser.add_argument(
        "-o", "--output", required=True, type=Path, metavar="DIR", help="folder for map.pgm and map.yaml"
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot map`; the exit code (argparse's own exits included)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or one line of error (2)
        return int(exc.code or 0)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        path = world_path(args.world)
        world = with_additions(load_world(path), [addition_path(name) for name in args.add])
        if args.randomise is not None:
            seed, profile = args.randomise
            world = vary(world, None, read_profile(profile or profile_beside(path)), seed).world
        grid = world_map(world, args.band or Band.at(LIDAR_HEIGHT), args.resolution, args.people)
        image, yaml = write_map(grid, args.output)
    except DescriptionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{PROG}: error: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    height, width = grid.occupied.shape
    print(
        f"wrote {yaml} and {image}: {width} × {height} cells of {grid.resolution} m from "
        f"({grid.origin[0]}, {grid.origin[1]}), {int(grid.occupied.sum())} occupied",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
