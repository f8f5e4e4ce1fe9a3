"""A fleet's layout, and its split into zones: where `--robots N` stands and which zone holds which robot.

`simbot-server --robots N` stands tug_1..tug_N in a grid from `--spawn`: `--columns C` columns
along x, COLUMN_SPACING apart, filled row by row, the rows along y ROW_SPACING apart (C = 1, the
default: one row along y). A fleet split into zones is a set of servers, each a band
XMIN ≤ x < XMAX of one world, each loading the same fleet and keeping the robots that stand in its
band (`--zone NAME:XMIN:XMAX`): this module is what the servers, `simbot launch --zones` and
`simbot handover` agree on, so that each robot is in exactly one zone (docs/fleets.md).
"""

from __future__ import annotations

import argparse
import bisect
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from simbot.description.poses import Pose

DEFAULT_SPAWN = (-2.5, 0.0, 0.1, 0.0)
ROW_SPACING = 1.5
"""Metres between the rows of a fleet along y (a tug is 0.5 m wide; its side cameras and lidars see the next)."""
COLUMN_SPACING = 5.0
"""Metres between the columns along x: a tug is 2.1 m long, so one driven halfway to the next column
(over the boundary of two zones between them) stops short of the tug standing there."""
MAX_FLEET = 1000
"""`--robots N` at most: a bound on a mistyped number, not a measured limit."""
TUG_BYTES = 3 << 20
"""Memory a kinematic tug with its full sensor set takes in its server (measured: 2.9 MB a tug
between 20 and 220 tugs, AMD EPYC, 2026-12-03)."""
WORLD_BYTES = 200 << 20
"""A server's own memory before its robots (measured: 187 MB with 20 tugs in the empty world)."""
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
"""A zone's name: ROS name tokens joined by `/`, a prefix of keys."""


@dataclass(frozen=True)
class Zone:
    """A zone server's name (the prefix of its world's own keys) and the band of x it owns."""

    name: str
    x_min: float
    x_max: float

    def holds(self, x: float) -> bool:
        return self.x_min <= x < self.x_max

    def __str__(self) -> str:
        """As `zone` reads it back, the same floats: `NAME:XMIN:XMAX`."""
        return f"{self.name}:{self.x_min!r}:{self.x_max!r}"


def zone(text: str) -> Zone:
    """An argparse type: `NAME:XMIN:XMAX` (either bound may be -inf or inf)."""
    name, _, bounds = text.partition(":")
    low, _, high = bounds.partition(":")
    try:
        x_min, x_max = float(low), float(high)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NS:XMIN:XMAX such as site_a:-inf:20, got {text!r}") from None
    name = name.strip("/")
    if not NAME.fullmatch(name) or math.isnan(x_min) or math.isnan(x_max) or x_min >= x_max:
        raise argparse.ArgumentTypeError(f"expected NS:XMIN:XMAX with a namespace and XMIN < XMAX, got {text!r}")
    return Zone(name, x_min, x_max)


@dataclass(frozen=True)
class Spot:
    """Where one robot of a fleet stands at the start: its name (its namespace too) and its pose."""

    name: str
    pose: Pose

    @property
    def x(self) -> float:
        return self.pose.xyz[0]


def fleet(spawn: Sequence[float], robots: int, columns: int = 1) -> list[Spot]:
    """tug_1..tug_N in `columns` columns along x from `spawn`, row by row along y, each at spawn's yaw."""
    x, y, z, yaw = spawn
    return [
        Spot(f"tug_{i + 1}", Pose((x + i % columns * COLUMN_SPACING, y + i // columns * ROW_SPACING, z), (0, 0, yaw)))
        for i in range(robots)
    ]


def split(spots: Sequence[Spot], names: Sequence[str]) -> list[Zone]:
    """One band of x per name, from -inf to inf, each holding about as many robots as the others.
    A boundary lies halfway between two neighbouring x at which robots stand (robots at one x stay
    together), at the gap whose count of robots below it is nearest to its share; ValueError when
    the robots stand at fewer different x than there are zones."""
    xs = sorted(spot.x for spot in spots)
    distinct = sorted(set(xs))
    count = len(names)
    if len(distinct) < count:
        raise ValueError(f"{count} zones need robots at {count} different x at least; they stand at {len(distinct)}")
    boundaries: list[float] = []
    first = 0
    for k in range(1, count):
        share = k * len(xs) / count
        last = len(distinct) - 1 - count + k  # a gap left for each boundary after this one
        gap = min(range(first, last + 1), key=lambda i: abs(bisect.bisect_right(xs, distinct[i]) - share))
        boundaries.append((distinct[gap] + distinct[gap + 1]) / 2)
        first = gap + 1
    bounds = [-math.inf, *boundaries, math.inf]
    return [Zone(name, low, high) for name, low, high in zip(names, bounds, bounds[1:], strict=False)]


def check_zones(zones: Sequence[Zone], spots: Sequence[Spot]) -> None:
    """ValueError naming the problem when two zones share a name or overlap, or a robot stands in no zone."""
    ordered = sorted(zones, key=lambda z: z.x_min)
    names = [z.name for z in zones]
    if len(set(names)) < len(names):
        raise ValueError(f"two zones named {next(n for n in names if names.count(n) > 1)}")
    for low, high in zip(ordered, ordered[1:], strict=False):
        if high.x_min < low.x_max:
            raise ValueError(f"zones {low.name} and {high.name} overlap from x {high.x_min:g} to {low.x_max:g}")
    for spot in spots:
        if not any(z.holds(spot.x) for z in zones):
            raise ValueError(f"{spot.name} stands at x {spot.x:g}, in no zone")


def in_zone(spots: Sequence[Spot], band: Zone | None) -> list[Spot]:
    """The robots a zone server holds: those standing in its band (all of them without one)."""
    return [spot for spot in spots if band is None or band.holds(spot.x)]
