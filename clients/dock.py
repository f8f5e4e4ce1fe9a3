"""Attach and detach the trolley from the keyboard (SPEC §5): t attach, r detach, q quit.

Attaching fixes the trolley to the robot where it stands, so it must only happen with the robot
under the trolley: their model origins (ground truth from `model/<name>/pose`) within 0.55 m of
each other in the XY plane at each of three checks 0.2 s apart. t starts the checks (the first at
once) and the attach command goes out after the third; a failed check ends the attempt with a
warning and nothing is sent. `--yaw-tolerance` also requires their headings to agree within that
many radians (off by default: the trolley is square and can be docked from any side).

A pose counts as unknown, hence far, until one has arrived and when none is stamped within the
last second (they come at 50 Hz). The client checks every 0.2 s and prints near / far when it
changes; the status line shows the distance and the joint's state from the latched
`detachable_joint/state`. Every period here is sim time (`clock`): a world at 0.5× or 4× docks the
same, and a paused one makes no checks. When the server restarts (or the world is reset) sim
time goes back: the client logs it once and the old run's poses count as unknown.

One robot of a fleet (`--robot-namespace tug_2`): attach, detach and the joint's state are that
robot's (`tug_2/attach`, `tug_2/detachable_joint/state`), the poses the world's ground truth
(`model/tug_2/pose`, `model/trolley/pose` at the bus's namespace). The robot is the model named
by the namespace's last segment (tug_2 of `--robots N`) unless `--robot` names it. The trolley is
`--trolley` (default `trolley`): the model whose nearness is checked, which must be the one the
robot's joint holds (the tug's SDF names `trolley`). The server refuses a trolley that another
robot holds, so one trolley serves a fleet one robot at a time.
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

from simbot.arguments import number
from simbot.bus import Node, Publisher, messages
from simbot.bus.tf_tree import planar_pose

from .common import (
    POLL_S,
    ClockSubscriber,
    Mailbox,
    Recent,
    SimTicker,
    client_parser,
    followed_model,
    run_client,
)
from .terminal import Terminal, terminal_input

logger = logging.getLogger(__name__)

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
STRING = "std_msgs/msg/String"
CHECKS = 3
POSE_TIMEOUT_S = 1.0
ATTACH, DETACH, QUIT = "t", "r", "q"
KEYS_HELP = ("simbot-dock   t attach   r detach   q quit",)

Planar = tuple[float, float, float]
"""(x, y, yaw) in the world."""


@dataclass(frozen=True)
class Nearness:
    """One check's verdict and how to say it."""

    near: bool
    text: str


class PoseWatch:
    """The latest planar pose of one model, forgotten when it grows stale."""

    def __init__(self, node: Node, model: str) -> None:
        self.model = model
        self._poses = Recent(node, f"/model/{model}/pose", POSE_STAMPED, POSE_TIMEOUT_S)  # the world's ground truth

    def pose(self, now: float | None) -> Planar | None:
        """(x, y, yaw), or None when none is stamped within POSE_TIMEOUT_S of sim time before `now`."""
        msg = self._poses.get(now)
        return planar_pose(msg.pose) if msg is not None else None


def nearness(robot: Planar | None, trolley: Planar | None, distance: float, yaw_tolerance: float | None) -> Nearness:
    """Whether the robot stands under the trolley: origins within `distance` in XY (and headings within `yaw_tolerance`)."""
    if robot is None or trolley is None:
        return Nearness(False, f"far/unknown (no recent pose of the {'robot' if robot is None else 'trolley'})")
    apart = math.hypot(trolley[0] - robot[0], trolley[1] - robot[1])
    text = f"{apart:.2f} m apart"
    if apart > distance:
        return Nearness(False, f"far ({text})")
    if yaw_tolerance is not None:
        yaw_error = abs(math.remainder(trolley[2] - robot[2], math.tau))
        if yaw_error > yaw_tolerance:
            return Nearness(False, f"far ({text}, headings {yaw_error:.2f} rad apart)")
    return Nearness(True, f"near ({text})")


@dataclass(frozen=True)
class Dock:
    """What `simbot-dock` docks: the robot and the trolley (model names), when they count as near, how often it checks."""

    robot: str
    trolley: str = "trolley"
    distance: float = 0.55
    """m in XY between their origins."""
    yaw_tolerance: float | None = None
    """rad between their headings; None: any heading."""
    check_period_s: float = 0.2
    """Sim time between the checks."""


class Docking:
    """The attempt in progress (near checks passed so far) and the joint's state as last reported."""

    def __init__(self, distance: float, attach: Publisher, detach: Publisher, terminal: Terminal) -> None:
        self.distance = distance
        self.joint = "unknown"
        self.passed: int | None = None
        """Checks passed in the attempt in progress; None when no attempt is."""
        self._attach = attach
        self._detach = detach
        self._terminal = terminal

    def press(self, key: str, verdict: Nearness) -> bool:
        """Act on a key; whether it started an attempt (t runs the first check on `verdict`, taken now)."""
        if key == ATTACH:
            if self.joint == "attached":
                self._terminal.message("already attached")
            elif self.passed is None:
                self.passed = 0
                self.check(verdict)
                return True
        elif key == DETACH:
            self.passed = None
            if self.joint == "detached":
                self._terminal.message("already detached")
            else:
                self._detach.put(messages.empty())
                self._terminal.message("detach sent")
        return False

    def check(self, verdict: Nearness) -> None:
        """Count a check of the attempt in progress; attach after the last, give up on a far one."""
        if self.passed is None:
            return
        if not verdict.near:
            self.passed = None
            logger.warning(
                "not attaching: trolley %s; the robot must stand under it (within %.2f m)", verdict.text, self.distance
            )
            return
        self.passed += 1
        if self.passed == CHECKS:
            self.passed = None
            self._attach.put(messages.empty())
            self._terminal.message(f"attach sent: {CHECKS} checks {verdict.text}")

    def status(self, verdict: Nearness) -> str:
        attempt = f" | checking {self.passed}/{CHECKS}" if self.passed is not None else ""
        return f"trolley {verdict.text} | joint {self.joint}{attempt}"


def _dock(node: Node, dock: Dock, terminal: Terminal, stop: threading.Event) -> None:
    """The loop: keys at once, a check every period, the joint's state as it changes."""
    clock = ClockSubscriber(node)
    robot, trolley = PoseWatch(node, dock.robot), PoseWatch(node, dock.trolley)
    joint_inbox: Mailbox[Any] = Mailbox(size=8)
    node.subscribe("detachable_joint/state", STRING, joint_inbox.put, latched=True)
    docking = Docking(
        dock.distance,
        node.publisher("attach", messages.Empty, drop=False),
        node.publisher("detach", messages.Empty, drop=False),
        terminal,
    )
    near: bool | None = None
    checks = SimTicker(dock.check_period_s)
    while not stop.is_set():
        keys = terminal.read_keys(POLL_S)
        if keys is None or QUIT in keys:
            return
        while (state := joint_inbox.get(timeout=0.0)) is not None:
            if state.data != docking.joint:
                docking.joint = state.data
                terminal.message(f"joint {state.data}")
        now = clock.now()
        verdict = nearness(robot.pose(now), trolley.pose(now), dock.distance, dock.yaw_tolerance)
        for key in keys:
            if docking.press(key, verdict):
                checks.restart(now)  # the attempt's next check, a period after its first
        if checks.due(now):
            docking.check(verdict)
        if verdict.near != near:
            near = verdict.near
            terminal.message(f"trolley {verdict.text}")
        terminal.status(docking.status(verdict))


def run(node: Node, stop: threading.Event, dock: Dock) -> int:
    """Docks from the keyboard (the terminal) until q, end of input or `stop`."""
    with Terminal(KEYS_HELP) as terminal:
        _dock(node, dock, terminal, stop)
    return 0


def _dock_of(args: argparse.Namespace) -> Dock:
    robot = args.robot or followed_model(args.robot_namespace)
    return Dock(robot, args.trolley, args.distance, args.yaw_tolerance, args.check_period)


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser(
        "simbot-dock", "Attach the trolley to the robot standing under it, or detach it, from the keyboard."
    )
    positive = number(float)
    parser.add_argument(
        "--robot",
        metavar="MODEL",
        help="the robot's model name (default: the last segment of --robot-namespace, else flexley_tug)",
    )
    parser.add_argument(
        "--trolley", default="trolley", metavar="MODEL", help="the trolley's model name (default trolley)"
    )
    parser.add_argument(
        "--distance",
        type=positive,
        default=0.55,
        metavar="M",
        help="attach only within this XY distance (default 0.55)",
    )
    parser.add_argument(
        "--yaw-tolerance",
        type=positive,
        metavar="RAD",
        help="attach only with headings this close (default: any heading)",
    )
    parser.add_argument(
        "--check-period",
        type=positive,
        default=0.2,
        metavar="S",
        help="seconds of sim time between the checks (default 0.2)",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot-dock`."""
    return run_client(
        build_parser(), argv, lambda args, node, stop: run(node, stop, _dock_of(args)), check=terminal_input
    )


if __name__ == "__main__":
    sys.exit(main())
