"""Drive the robot from the keyboard (SPEC §5), refusing to drive into what the lidars see in its path.

Keys latch, as in ROS's teleop_twist_keyboard: w forward, s backward, a turn left, d turn right
(each sets the whole command: a and d turn in place), x or space stop, q quit. The command
goes out on `cmd_vel` at 10 Hz of sim time (`clock`, so a world at 0.5× or 4× gets the same
commands per simulated second), and at once when a key changes it; a zero command goes out when
the program ends, however it ends, and the terminal is given back as it was.

The obstacle stop looks at the robot's path, not the lidars' whole 160° view, so that a shelf
beside the robot does not stop it. Each ray's end point is taken into `base_link` with the
lidar's pose from `tf_static` (the scan's frame), and the points in the corridor the robot
sweeps count: |y| ≤ width/2 + margin, ahead of base_link (x > 0) for forward from `lidar_front`,
behind it (x < 0) for backward from `lidar_back`. The distance is the ray's range, measured from
the lidar (6 cm inside the chassis' front face, 10 cm inside its back face): forward is refused
while the front lidar sees something closer than 0.5 m in the path, as SPEC says. Scans come at
5 Hz, so a robot driving at 0.5 m/s stops about 0.1 m inside that distance (0.39 m measured).

Unknown is not clear: with no scan stamped within `--scan-timeout` seconds of sim time (five
scans missed), or before
`tf_static` gives the lidar's pose, driving that way is refused, because a silent lidar says
nothing about what is ahead. Turning in place is never refused. The client logs once each time
a drive becomes blocked; the status line shows it for as long as it lasts.

When the server restarts (or the world is reset) sim time goes back: the client logs it once,
the scans of the old run count as none, and the latched command goes on to the new robot at its
clock's first tick, refused as ever until the new lidars see the path clear.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.tf_tree import Matrix
from simbot.transform import matmul

from .common import POLL_S, ClockSubscriber, Recent, SimTicker, StaticTransforms, client_parser, run_client
from .terminal import Terminal, terminal_input

logger = logging.getLogger(__name__)

LASER_SCAN = "sensor_msgs/msg/LaserScan"

MOVES = {"w": (1, 0), "s": (-1, 0), "a": (0, 1), "d": (0, -1), "x": (0, 0), " ": (0, 0)}
"""Key → (sign of the linear speed, sign of the turn rate)."""
QUIT = "q"
KEYS_HELP = (
    "simbot-teleop   w forward   s backward   a turn left   d turn right   (keys latch)",
    "                x or space stop   q quit",
)
DIRECTIONS = {1: "forward", -1: "backward"}


@dataclass(frozen=True)
class Settings:
    """What the options set: speeds, the path corridor and the obstacle stop."""

    speed: float
    turn_rate: float
    half_width: float
    stop_distance: float
    scan_timeout: float
    period: float
    base_frame: str

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Settings:
        return cls(
            speed=args.speed,
            turn_rate=args.turn_rate,
            half_width=args.width / 2 + args.margin,
            stop_distance=args.stop_distance,
            scan_timeout=args.scan_timeout,
            period=1.0 / args.rate,
            base_frame=args.base_frame,
        )


def path_ranges(scan: Any, sensor_in_base: Matrix, half_width: float, ahead: bool) -> npt.NDArray[np.float64]:
    """The ranges of the rays whose end points lie in the robot's path: |y| ≤ half_width, ahead (x > 0) or behind (x < 0) of the base."""
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    angles = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    reach = np.where(valid, ranges, 0.0)
    ends = np.stack([reach * np.cos(angles), reach * np.sin(angles), np.zeros_like(reach), np.ones_like(reach)])
    x, y = matmul(sensor_in_base, ends)[:2]
    on_side = x > 0 if ahead else x < 0
    return ranges[valid & on_side & (np.abs(y) <= half_width)]


class PathWatch:
    """One lidar watching one direction of travel: the nearest return in the path, or None when unknown."""

    def __init__(self, node: Node, topic: str, ahead: bool, settings: Settings) -> None:
        self.ahead = ahead
        self._scans = Recent(node, topic, LASER_SCAN, settings.scan_timeout)

    def nearest(self, transforms: StaticTransforms, settings: Settings, now: float | None) -> float | None:
        """Metres from the lidar to the nearest return in the path (inf when clear); None with no recent scan or no sensor pose."""
        scan = self._scans.get(now)
        if scan is None:
            return None
        sensor_in_base = transforms.pose(scan.header.frame_id)
        if sensor_in_base is None:
            return None
        ranges = path_ranges(scan, sensor_in_base, settings.half_width, self.ahead)
        return float(ranges.min()) if ranges.size else math.inf


class Teleop:
    """The latched command, the obstacle stop on it, and the one log line per blocking."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.move = (0, 0)
        self.blocked: str | None = None
        """The direction refused at the last tick, if any."""

    def press(self, key: str) -> bool:
        """Latch the move of `key`; whether the command changed."""
        move = MOVES.get(key)
        if move is None or move == self.move:
            return False
        self.move = move
        return True

    def command(self, ahead: float | None, behind: float | None) -> tuple[float, float]:
        """(linear, angular) to send now: the latched move, with a drive into the path's obstacle refused."""
        linear_sign, angular_sign = self.move
        blocked = None
        if linear_sign:
            view = ahead if linear_sign > 0 else behind
            if view is None or view < self.settings.stop_distance:
                blocked = DIRECTIONS[linear_sign]
                if blocked != self.blocked:
                    logger.warning("%s blocked: %s; not driving", blocked, _obstacle(view, linear_sign))
        self.blocked = blocked
        linear = 0.0 if blocked else linear_sign * self.settings.speed
        return linear, angular_sign * self.settings.turn_rate

    def status(self, linear: float, angular: float, ahead: float | None, behind: float | None) -> str:
        state = f"BLOCKED {self.blocked}" if self.blocked else "ok"
        return f"v {linear:+.2f} m/s  w {angular:+.2f} rad/s | ahead {_distance(ahead)}  behind {_distance(behind)} | {state}"


def _distance(view: float | None) -> str:
    if view is None:
        return "unknown"
    return "clear" if math.isinf(view) else f"{view:.2f} m"


def _obstacle(view: float | None, sign: int) -> str:
    lidar = "front" if sign > 0 else "back"
    if view is None:
        return f"no recent scan from the {lidar} lidar"
    return f"obstacle {view:.2f} m from the {lidar} lidar in the path"


def _drive(node: Node, settings: Settings, terminal: Terminal, stop: threading.Event) -> None:
    """The loop: keys in, a command out every period (and at once on a change), the status line."""
    transforms = StaticTransforms(node, settings.base_frame)
    front = PathWatch(node, "lidar_front", True, settings)
    back = PathWatch(node, "lidar_back", False, settings)
    cmd_vel = node.publisher("cmd_vel", messages.Twist, drop=False)
    clock = ClockSubscriber(node)
    ticker = SimTicker(settings.period)
    teleop = Teleop(settings)
    try:
        while not stop.is_set():
            keys = terminal.read_keys(POLL_S)
            if keys is None:
                return
            changed = False
            for key in keys:
                if key == QUIT:
                    return
                changed = teleop.press(key) or changed
            now = clock.now()
            if changed:
                ticker.restart(now)
            elif not ticker.due(now):
                continue
            transforms.refresh()
            ahead, behind = front.nearest(transforms, settings, now), back.nearest(transforms, settings, now)
            linear, angular = teleop.command(ahead, behind)
            cmd_vel.put(messages.twist((linear, 0.0, 0.0), (0.0, 0.0, angular)))
            terminal.status(teleop.status(linear, angular, ahead, behind))
    finally:
        cmd_vel.put(messages.twist())


def run(node: Node, stop: threading.Event, settings: Settings) -> int:
    """Drives from the keyboard (the terminal) until q, end of input or `stop`; a stop command last."""
    with Terminal(KEYS_HELP) as terminal:
        _drive(node, settings, terminal, stop)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot-teleop", "Drive the robot from the keyboard; stops short of obstacles in its path.")
    positive = number(float)
    parser.add_argument(
        "--speed", type=positive, default=0.5, metavar="M/S", help="forward and backward speed (default 0.5)"
    )
    parser.add_argument(
        "--turn-rate", type=positive, default=0.5, metavar="RAD/S", help="turn rate in place (default 0.5)"
    )
    parser.add_argument(
        "--stop-distance",
        type=positive,
        default=0.5,
        metavar="M",
        help="refuse to drive towards an obstacle closer than this to the lidar (default 0.5)",
    )
    parser.add_argument(
        "--width", type=positive, default=0.5, metavar="M", help="the robot's width, for its path (default 0.5)"
    )
    parser.add_argument(
        "--margin",
        type=number(float, at_least_zero=True),
        default=0.1,
        metavar="M",
        help="added to each side of the path (default 0.1)",
    )
    parser.add_argument(
        "--scan-timeout",
        type=positive,
        default=1.0,
        metavar="S",
        help="a lidar silent this long counts as blocked (default 1.0)",
    )
    parser.add_argument("--rate", type=positive, default=10.0, metavar="HZ", help="commands per second (default 10)")
    parser.add_argument(
        "--base-frame",
        default="base_link",
        metavar="FRAME",
        help="the frame the path is measured in (default base_link)",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot-teleop`."""
    return run_client(
        build_parser(), argv, lambda args, node, stop: run(node, stop, Settings.from_args(args)), check=terminal_input
    )


if __name__ == "__main__":
    sys.exit(main())
