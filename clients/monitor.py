"""`simbot monitor`: a live table of the sensors, refreshed about once a second.

What it shows, and where from:
- the world's sim time, real-time factor and mode: world control's `state` service (the world
  found on the graph, or `--world`);
- every live key whose type it can summarise, found on the graph and subscribed to as it
  appears (so the merger's `scan` and the stitcher's `camera_360/camera_info` show up when those
  clients start): its achieved rate (messages per wall second over the last 3 s, counted as they
  arrive) and its latest message in brief: the IMU's acceleration and turn rate, each scan's
  nearest return, odometry and model poses, joint speeds, image sizes from camera_info, short
  strings such as the docking state;
- the server's cameras, from the world state's sensor figures (size, rate per sim second,
  skipped frames): images are never subscribed to, since a subscriber makes the server render;
- the systems the world runs without because their SDF parameters are bad, from the world
  state's `systems_left_out`: a row each, `left out` and why (a lidar that vanished says so here).

Rates count wall seconds, and the heading asks the world each time, so a server that restarts
shows again within a refresh or two of coming back (its sim time from zero, which the monitor
logs once on stderr, as every client does); until then the heading says the world does not answer.

With `--robot-namespace tug_2` it shows one robot of a fleet: that robot's keys, named relative to
its namespace as its nodes see them (`lidar_front` for `tug_2/lidar_front`), the world's clock
and the robot's ground truth (`/clock`, `/model/tug_2/pose`: absolute names, at the bus's
namespace), and the cameras of its model (`tug_2/...` in the world state); the other robots'
keys and cameras are left out.

On a terminal it is a full-screen view redrawn in place (`terminal.FullScreen`: the alternate
screen, left on any exit, so Ctrl-C gives back the terminal as it was); elsewhere (a pipe, a file)
each refresh is a block of lines followed by a blank line. SIGINT / SIGTERM end it with code 0.
"""

from __future__ import annotations

import math
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from simbot.arguments import number
from simbot.bus import Node, ServiceError, messages
from simbot.bus.tf_tree import planar_pose

from .common import ClockSubscriber, Mailbox, client_parser, followed_model, run_client
from .terminal import FullScreen
from .topics import Topic, Traffic, format_rate, latched, live_topics, world_names

REFRESH_S = 1.0
RATE_HORIZON_S = 3.0
STATE_TIMEOUT_S = 0.5
STRING_LIMIT = 40
COLUMNS = ("KEY", "RATE", "LATEST")


# --- one line per message type --------------------------------------------------------------


def _xyz(v: Any, digits: int) -> str:
    return " ".join(f"{value:+.{digits}f}" for value in (v.x, v.y, v.z))


def imu_text(msg: Any) -> str:
    """Specific force (≈ +9.8 up at rest) and turn rate in the IMU frame."""
    return f"accel {_xyz(msg.linear_acceleration, 2)} m/s²; gyro {_xyz(msg.angular_velocity, 3)} rad/s"


def scan_text(msg: Any) -> str:
    """The nearest valid return: its range and bearing in the scan's frame."""
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    valid = np.isfinite(ranges) & (ranges >= msg.range_min) & (ranges <= msg.range_max)
    if not valid.any():
        return f"no returns of {ranges.size} ({msg.header.frame_id})"
    index = int(np.argmin(np.where(valid, ranges, np.inf)))
    bearing = math.degrees(msg.angle_min + index * msg.angle_increment)
    return f"nearest {ranges[index]:.2f} m at {bearing:+.0f}°; {int(valid.sum())}/{ranges.size} returns ({msg.header.frame_id})"


def odometry_text(msg: Any) -> str:
    """Planar pose in the odom frame and the body's speeds."""
    x, y, yaw = planar_pose(msg.pose.pose)
    twist = msg.twist.twist
    return f"x {x:+.2f} y {y:+.2f} m, yaw {math.degrees(yaw):+.1f}°; v {twist.linear.x:+.2f} m/s, ω {twist.angular.z:+.2f} rad/s"


def pose_text(msg: Any) -> str:
    """A ground-truth pose, planar, in its frame."""
    x, y, yaw = planar_pose(msg.pose)
    return (
        f"x {x:+.2f} y {y:+.2f} z {msg.pose.position.z:+.2f} m, yaw {math.degrees(yaw):+.1f}° ({msg.header.frame_id})"
    )


def joints_text(msg: Any) -> str:
    """Each joint's speed."""
    return (
        "; ".join(f"{name} {float(v):+.2f} rad/s" for name, v in zip(msg.name, msg.velocity))
        or f"{len(msg.name)} joints"
    )


def camera_info_text(msg: Any) -> str:
    """The image size a camera announces."""
    return f"{msg.width}x{msg.height}"


def clock_text(msg: Any) -> str:
    """The sim time the clock carries."""
    return f"sim time {messages.stamp_ns(msg.clock) / 1e9:.2f} s"


def string_text(msg: Any) -> str:
    """A short string as it is (the docking state); a long one (a URDF) by its length."""
    text = str(msg.data)
    return text if len(text) <= STRING_LIMIT and "\n" not in text else f"{len(text)} characters"


SUMMARIES: dict[str, Callable[[Any], str]] = {
    "rosgraph_msgs/msg/Clock": clock_text,
    "nav_msgs/msg/Odometry": odometry_text,
    "sensor_msgs/msg/Imu": imu_text,
    "sensor_msgs/msg/LaserScan": scan_text,
    "sensor_msgs/msg/CameraInfo": camera_info_text,
    "sensor_msgs/msg/JointState": joints_text,
    "geometry_msgs/msg/PoseStamped": pose_text,
    "std_msgs/msg/String": string_text,
}
"""The types monitor subscribes to, in the order of its rows. Images are missing on purpose (see above)."""
RANKS = {typename: rank for rank, typename in enumerate(SUMMARIES)}


def camera_text(figures: Mapping[str, Any]) -> str:
    """A server camera's line from the world state: size, frames skipped, or that nobody watches it."""
    width, height = figures.get("size", ("?", "?"))
    if "error" in figures:
        return f"{width}x{height}; {figures['error']}"
    if not figures.get("rate_hz"):
        return f"{width}x{height}; not rendered (nobody subscribes to the image)"
    return f"{width}x{height}; {figures.get('skipped', 0)} frames skipped"


def left_out_rows(state: Mapping[str, Any] | None, model: str) -> list[tuple[str, str, str]]:
    """A row per system the world left out (of `model`'s, when one is followed): its name, `left out`, why."""
    entries: list[Mapping[str, str]] = (state or {}).get("systems_left_out", [])
    return [
        (entry["name"], "left out", entry["reason"])
        for entry in entries
        if not model or entry["name"].startswith(f"{model}/")
    ]


def state_line(world: str | None, state: Mapping[str, Any] | None) -> str:
    """The heading: world, sim time, real-time factor, mode."""
    if world is None:
        return "world ?: no world control on the bus (yet)"
    if state is None:
        return f"world {world}: world/{world}/state does not answer"
    paused = ", paused" if state.get("paused") else ""
    rtf = state.get("real_time_factor")
    rtf_text = f"{rtf:.2f}" if isinstance(rtf, (int, float)) else "?"
    return f"world {world}  sim time {state.get('sim_time', 0.0):.2f} s  real-time factor {rtf_text}  ({state.get('mode', '?')}{paused})"


# --- the monitor ----------------------------------------------------------------------------


def followed_topics(topics: Mapping[str, Topic], robot_namespace: str, model: str) -> dict[str, Topic]:
    """The topics to show, by the name shown: all of them; in a robot's namespace, the robot's (named
    relative to it) and the world's clock and the robot's ground truth (named absolute)."""
    if not robot_namespace:
        return dict(topics)
    prefix = robot_namespace.strip("/") + "/"
    world = {"clock", f"model/{model}/pose"}
    shown = {name.removeprefix(prefix): topic for name, topic in topics.items() if name.startswith(prefix)}
    return shown | {f"/{name}": topic for name, topic in topics.items() if name in world}


class Monitor:
    """Subscriptions to every summarisable key, their latest messages and rates, and the table."""

    def __init__(self, node: Node, world: str | None) -> None:
        self.node = node
        self.world = world
        self.model = followed_model(node.robot_namespace, default="")
        """The followed robot's model; empty: none followed, every model's cameras are shown."""
        self.traffic = Traffic(RATE_HORIZON_S)
        self.types: dict[str, str] = {}
        self.inboxes: dict[str, Mailbox[Any]] = {}
        self.latest: dict[str, str] = {}
        self.clock = ClockSubscriber(node)  # says when sim time goes back

    def follow_graph(self) -> None:
        """Subscribes to the keys that appeared since the last call (and finds the world).

        Only latched keys get a late joiner's history: on the others, the last message and the
        first live one would arrive together and read as a rate of thousands of Hz.
        """
        topics = live_topics(self.node)
        if self.world is None:
            self.world = next(iter(world_names(topics.values())), None)
        shown = followed_topics(topics, self.node.robot_namespace, self.model)
        new = {
            name: t
            for name, t in shown.items()
            if name not in self.types and "pub" in t.kinds and t.typename in SUMMARIES
        }
        held = latched(self.node.session, [topic.data_key for topic in new.values()])
        for name, topic in new.items():
            inbox: Mailbox[Any] = Mailbox(1)
            self.types[name], self.inboxes[name] = topic.typename, inbox
            # by its name at the bus's namespace: the same key whatever robot is followed
            self.node.subscribe(
                f"/{topic.name}", topic.typename, self._arrival(name, inbox), latched=topic.data_key in held
            )

    def _arrival(self, name: str, inbox: Mailbox[Any]) -> Callable[[Any], None]:
        def arrived(msg: Any) -> None:  # Zenoh thread: count and keep the newest
            self.traffic.count(name)
            inbox.put(msg)

        return arrived

    def state(self) -> dict[str, Any] | None:
        """The world state, or None while there is no world or it does not answer in time (the table goes on)."""
        if self.world is None:
            return None
        try:
            return self.node.call(f"world/{self.world}/state", {}, timeout=STATE_TIMEOUT_S)
        except (TimeoutError, ServiceError):
            return None

    def rows(self, state: Mapping[str, Any] | None) -> list[tuple[str, str, str]]:
        """One row per followed key (latest message summarised here, in the loop), then the cameras,
        then the systems left out."""
        for name, inbox in self.inboxes.items():
            msg = inbox.get(0.0)
            if msg is not None:
                self.latest[name] = SUMMARIES[self.types[name]](msg)
        rows = [
            (name, format_rate(self.traffic.figures(name)), self.latest.get(name, "no message yet"))
            for name in sorted(self.types, key=lambda n: (RANKS[self.types[n]], n))
        ]
        sensors: Mapping[str, Any] = (state or {}).get("sensors", {})
        for name, figures in sensors.items():
            if "size" in figures and (not self.model or name.startswith(f"{self.model}/")):
                rows.append((name, f"{figures.get('rate_hz', 0.0):.1f} Hz", camera_text(figures)))
        return rows + left_out_rows(state, self.model)

    def frame(self) -> str:
        """The whole table as text."""
        self.follow_graph()
        state = self.state()
        rows = self.rows(state)
        widths = [max(len(row[i]) for row in (COLUMNS, *rows)) for i in range(2)]
        lines = [state_line(self.world, state)]
        lines += [
            f"{key.ljust(widths[0])}  {rate.rjust(widths[1])}  {latest}" for key, rate, latest in (COLUMNS, *rows)
        ]
        return "\n".join(lines)


def run(node: Node, stop: threading.Event, world: str | None, period_s: float) -> int:
    """Shows the table of `world` (None: the one on the bus) every `period_s` until `stop`."""
    monitor = Monitor(node, world)
    monitor.follow_graph()
    if not sys.stdout.isatty():
        while not stop.wait(period_s):  # the first table after a period, when the subscriptions have data
            sys.stdout.write(f"{monitor.frame()}\n\n")
            sys.stdout.flush()
        return 0
    with FullScreen() as screen:
        screen.draw(f"{state_line(monitor.world, None)}\n(the first table in {period_s:g} s)")
        while not stop.wait(period_s):
            screen.draw(monitor.frame())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot monitor [--world NAME] [--period S]`."""
    parser = client_parser(
        "simbot monitor", "A live table of every sensor: rates, latest values, sim time and real-time factor."
    )
    parser.add_argument("--world", metavar="NAME", help="the world whose state to show (default: the one on the bus)")
    parser.add_argument(
        "--period",
        type=number(float),
        default=REFRESH_S,
        metavar="SECONDS",
        help=f"refresh period (default {REFRESH_S:g})",
    )
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, args.world, args.period))


if __name__ == "__main__":
    sys.exit(main())
