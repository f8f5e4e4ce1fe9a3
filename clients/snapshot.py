"""`simbot snapshot`: the panorama and a top-down map of the merged scan, as PNGs a person can look at.

    simbot snapshot --out DIR [--timeout S] [--panorama] [--map]

- `DIR/panorama.png`: the latest `camera_360/image_raw` (the stitcher's), as it is.
- `DIR/map.png`: the latest `scan` (the merger's, in `base_link`) seen from above, x forward up the
  image and y to the left (REP-103), 2 cm a pixel over ±6 m, with a metre grid, the x (red) and
  y (green) axes, a 1 m scale bar, the robot's footprint and the trolley's deck where
  `model/trolley/pose` puts it relative to `model/flexley_tug/pose`.

The footprint is the box of base_link's collision in `robot_description`, so the map follows the
robot that is actually running; without it, SPEC's 2.1 × 0.5 m chassis. The model poses are
base_footprint's, which lies under base_link (REP-105), so the trolley's place relative to the
robot is the same in either frame.

It waits up to `--timeout` seconds for the keys each image needs; once those are in, it gives the
keys that only add detail (the description, the poses) a moment more, so that a world without a
trolley costs no full timeout. A key that stayed silent is one line on stderr, and the images that
could be made are still written. Exit code 0 when at least one image was written, else 2.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.messages import stamp_ns
from simbot.bus.tf_tree import planar_pose
from simbot.transform import matmul

from .common import EXIT_USAGE, ClientError, Mailbox, client_parser, run_client

PROG = "simbot snapshot"
PANORAMA = "camera_360/image_raw"
SCAN = "scan"
DESCRIPTION = "robot_description"
ROBOT_POSE = "model/flexley_tug/pose"
TROLLEY_POSE = "model/trolley/pose"

TYPES = {
    PANORAMA: "sensor_msgs/msg/Image",
    SCAN: "sensor_msgs/msg/LaserScan",
    DESCRIPTION: "std_msgs/msg/String",
    ROBOT_POSE: "geometry_msgs/msg/PoseStamped",
    TROLLEY_POSE: "geometry_msgs/msg/PoseStamped",
}
LATCHED = {DESCRIPTION}
NEEDS = {"panorama": (PANORAMA,), "map": (SCAN,)}
"""The keys without which an image cannot be made."""
DETAILS = {"panorama": (), "map": (DESCRIPTION, ROBOT_POSE, TROLLEY_POSE)}
"""The keys that only add to an image."""

SPEC_CHASSIS_M = (2.1, 0.5)
"""SPEC §1's chassis (base_link's collision box, length × width): the footprint when no description comes."""
TROLLEY_DECK_M = 1.4
"""The trolley's square deck (worlds/models/trolley): the trolley is a world model, whose description is not on the bus."""
HINTS = {
    PANORAMA: "is the stitcher running?",
    SCAN: "is the merger running?",
    DESCRIPTION: f"the footprint is SPEC's {SPEC_CHASSIS_M[0]:g} × {SPEC_CHASSIS_M[1]:g} m chassis",
    ROBOT_POSE: "the trolley is not drawn",
    TROLLEY_POSE: "the trolley is not drawn",
}

DEFAULT_TIMEOUT_S = 10.0
DETAIL_GRACE_S = 1.0
POLL_S = 0.1
RESOLUTION_M = 0.02
HALF_EXTENT_M = 6.0

Colour = tuple[int, int, int]
# BGR, drawn without anti-aliasing so that each thing keeps its own colour
BACKGROUND: Colour = (255, 255, 255)
GRID: Colour = (225, 225, 225)
TEXT: Colour = (70, 70, 70)
SCAN_POINTS: Colour = (0, 0, 0)
ROBOT_FILL: Colour = (140, 190, 250)
ROBOT_EDGE: Colour = (13, 84, 217)
TROLLEY: Colour = (200, 110, 20)
X_AXIS: Colour = (0, 0, 220)
Y_AXIS: Colour = (0, 160, 0)
X_AXIS_M, Y_AXIS_M = 1.5, 1.0
"""Axis arrows from the robot's centre, long enough to reach out of its footprint."""

BGR_OF = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR}


@dataclass(frozen=True)
class Box:
    """A rectangle in the map's frame: centre, yaw, length along its x, width along its y."""

    x: float
    y: float
    yaw: float
    length: float
    width: float

    def corners(self) -> npt.NDArray[np.float64]:
        """The four corners (x, y), counter-clockwise from front-left."""
        half = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * (self.length / 2, self.width / 2)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return matmul(half, np.array([[c, s], [-s, c]])) + (self.x, self.y)


SPEC_FOOTPRINT = Box(0.0, 0.0, 0.0, *SPEC_CHASSIS_M)


@dataclass(frozen=True)
class MapView:
    """Metres in the scan's frame to pixels: x up, y left, the frame's origin at the centre."""

    resolution: float = RESOLUTION_M
    half_extent: float = HALF_EXTENT_M

    @property
    def size(self) -> int:
        """Pixels a side: odd, so that the origin is a pixel's centre and ±half_extent both fit."""
        return 2 * round(self.half_extent / self.resolution) + 1

    def pixels(self, xy: npt.ArrayLike) -> npt.NDArray[np.int32]:
        """(column, row) of each point (x, y), rounded to the nearest pixel."""
        points = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        centre = self.size // 2
        columns, rows = centre - points[:, 1] / self.resolution, centre - points[:, 0] / self.resolution
        return np.rint(np.column_stack((columns, rows))).astype(np.int32)


def footprint(urdf: str) -> Box | None:
    """base_link's collision box from URDF text (its origin's x, y and yaw kept), or None when there is none."""
    try:
        root = ET.fromstring(urdf)
    except ET.ParseError:
        return None
    for collision in root.findall("link[@name='base_link']/collision"):
        box = collision.find("geometry/box")
        origin = collision.find("origin")
        try:
            size = _triple(box, "size")
            xyz, rpy = _triple(origin, "xyz"), _triple(origin, "rpy")
        except ValueError:
            return None
        if size is not None:
            x, y, _ = xyz or (0.0, 0.0, 0.0)
            return Box(x, y, (rpy or (0.0, 0.0, 0.0))[2], size[0], size[1])
    return None


def _triple(element: ET.Element | None, attribute: str) -> tuple[float, float, float] | None:
    """Three numbers from a URDF attribute, None when absent; ValueError when malformed."""
    text = element.get(attribute) if element is not None else None
    if text is None:
        return None
    a, b, c = (float(v) for v in text.split())
    return a, b, c


def relative_box(robot: Any, trolley: Any, side: float) -> Box:
    """The trolley's deck in the robot's frame, from two PoseStamped in the world."""
    xr, yr, yaw_r = planar_pose(robot.pose)
    xt, yt, yaw_t = planar_pose(trolley.pose)
    dx, dy = xt - xr, yt - yr
    c, s = math.cos(yaw_r), math.sin(yaw_r)
    return Box(c * dx + s * dy, -s * dx + c * dy, yaw_t - yaw_r, side, side)


def scan_points(scan: Any) -> npt.NDArray[np.float64]:
    """(x, y) of every valid return (finite, within the range limits) in the scan's frame."""
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    angles = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    return np.column_stack((ranges[valid] * np.cos(angles[valid]), ranges[valid] * np.sin(angles[valid])))


def draw_grid(image: npt.NDArray[np.uint8], view: MapView) -> None:
    """A line every metre, both ways."""
    metres = np.arange(-math.floor(view.half_extent), math.floor(view.half_extent) + 1)
    last = view.size - 1
    for m in metres:
        col, row = view.pixels((m, m))[0]
        cv2.line(image, (0, int(row)), (last, int(row)), GRID, 1, cv2.LINE_8)
        cv2.line(image, (int(col), 0), (int(col), last), GRID, 1, cv2.LINE_8)


def draw_box(image: npt.NDArray[np.uint8], view: MapView, box: Box, edge: Colour, fill: Colour | None = None) -> None:
    polygon = view.pixels(box.corners()).reshape(-1, 1, 2)
    if fill is not None:
        cv2.fillPoly(image, [polygon], fill, cv2.LINE_8)
    cv2.polylines(image, [polygon], True, edge, 2, cv2.LINE_8)


def draw_axes(image: npt.NDArray[np.uint8], view: MapView) -> None:
    """x (red) forward and y (green) left from the origin, labelled, as RViz colours them."""
    origin, x_tip, y_tip = (tuple(int(v) for v in p) for p in view.pixels([(0, 0), (X_AXIS_M, 0), (0, Y_AXIS_M)]))
    cv2.arrowedLine(image, origin, x_tip, X_AXIS, 2, cv2.LINE_8, tipLength=0.15)
    cv2.arrowedLine(image, origin, y_tip, Y_AXIS, 2, cv2.LINE_8, tipLength=0.2)
    cv2.putText(image, "x", (x_tip[0] + 6, x_tip[1] + 10), cv2.FONT_HERSHEY_SIMPLEX, 0.5, X_AXIS, 1, cv2.LINE_AA)
    cv2.putText(image, "y", (y_tip[0] - 6, y_tip[1] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, Y_AXIS, 1, cv2.LINE_AA)


def draw_legend(image: npt.NDArray[np.uint8], view: MapView, caption: str) -> None:
    """The caption at the top left, a 1 m scale bar at the bottom left."""
    cv2.putText(image, caption, (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, TEXT, 1, cv2.LINE_AA)
    left, bottom = 10, view.size - 14
    right = left + round(1.0 / view.resolution)
    cv2.rectangle(image, (left, bottom - 3), (right, bottom), TEXT, -1, cv2.LINE_8)
    cv2.putText(image, "1 m", (right + 6, bottom + 2), cv2.FONT_HERSHEY_SIMPLEX, 0.45, TEXT, 1, cv2.LINE_AA)


def render_map(scan: Any, robot: Box, trolley: Box | None, view: MapView = MapView()) -> npt.NDArray[np.uint8]:
    """The top-down map (BGR): grid, trolley, robot, axes, scan returns, legend."""
    image = np.full((view.size, view.size, 3), BACKGROUND, dtype=np.uint8)
    draw_grid(image, view)
    if trolley is not None:
        draw_box(image, view, trolley, TROLLEY)
    draw_box(image, view, robot, ROBOT_EDGE, ROBOT_FILL)
    draw_axes(image, view)
    for col, row in view.pixels(scan_points(scan)):
        cv2.circle(image, (int(col), int(row)), 1, SCAN_POINTS, -1, cv2.LINE_8)
    stamp = stamp_ns(scan.header) / 1e9
    caption = f"{SCAN} in {scan.header.frame_id or '?'} at {stamp:.3f} s | {view.resolution * 100:g} cm/px, grid 1 m"
    draw_legend(image, view, caption)
    return image


def panorama_pixels(msg: Any) -> npt.NDArray[np.uint8]:
    """The image as BGR (or grey) pixels for cv2; ValueError for an encoding it cannot show."""
    try:
        pixels = messages.image_pixels(msg)
    except ValueError as exc:
        raise ValueError(f"{PANORAMA}: {exc}") from None
    if msg.encoding in BGR_OF:
        return np.asarray(cv2.cvtColor(pixels, BGR_OF[msg.encoding]), dtype=np.uint8)
    return np.ascontiguousarray(pixels)


def _deliver(box: Mailbox[tuple[str, Any]], key: str, msg: Any) -> None:
    """Zenoh thread: the message to the loop, tagged with its key."""
    box.put((key, msg))


def collect(
    box: Mailbox[tuple[str, Any]], needs: set[str], details: set[str], timeout: float, stop: threading.Event
) -> dict[str, Any]:
    """The latest message of each key: until all came, `timeout` passed, or the details' grace ran out."""
    deadline = time.monotonic() + timeout
    got: dict[str, Any] = {}
    while not stop.is_set() and not (needs | details) <= got.keys():
        left = deadline - time.monotonic()
        if left <= 0:
            break
        item = box.get(min(POLL_S, left))
        if item is None:
            continue
        got[item[0]] = item[1]
        if needs <= got.keys():
            deadline = min(deadline, time.monotonic() + DETAIL_GRACE_S)
    return got


def write(path: Path, image: npt.NDArray[np.uint8]) -> Path:
    """Write `image` as a PNG at `path` (cv2 says only True or False, so the error names the path)."""
    if not cv2.imwrite(str(path), image):
        raise ClientError(f"{path}: cannot write the PNG")
    return path


def make_map(got: dict[str, Any]) -> tuple[npt.NDArray[np.uint8], list[str]]:
    """The map from what came, and a note for each detail it had to do without."""
    notes = []
    robot = footprint(got[DESCRIPTION].data) if DESCRIPTION in got else None
    if DESCRIPTION in got and robot is None:
        notes.append(f"{DESCRIPTION} has no base_link collision box: {HINTS[DESCRIPTION]}")
    trolley = None
    if ROBOT_POSE in got and TROLLEY_POSE in got:
        trolley = relative_box(got[ROBOT_POSE], got[TROLLEY_POSE], TROLLEY_DECK_M)
    return render_map(got[SCAN], robot or SPEC_FOOTPRINT, trolley), notes


def snapshot(node: Node, stop: threading.Event, out: Path, images: Sequence[str], timeout_s: float) -> int:
    """Wait up to `timeout_s` for the keys of `images` (of NEEDS), write those that can be made into
    `out`, report what was silent; the exit code."""
    needs = {key for name in images for key in NEEDS[name]}
    details = {key for name in images for key in DETAILS[name]}
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ClientError(f"--out {out}: {exc.strerror or exc}") from None
    box: Mailbox[tuple[str, Any]] = Mailbox(size=64)
    for key in sorted(needs | details):
        node.subscribe(key, TYPES[key], functools.partial(_deliver, box, key), latched=key in LATCHED)
    start = time.monotonic()
    got = collect(box, needs, details, timeout_s, stop)
    if stop.is_set():
        return 0
    waited = time.monotonic() - start
    notes = [
        f"no {key} within {round(waited, 1):g} s: {HINTS[key]}" for key in sorted(needs | details) if key not in got
    ]
    written = []
    if "panorama" in images and PANORAMA in got:
        try:
            written.append(write(out / "panorama.png", panorama_pixels(got[PANORAMA])))
        except ValueError as exc:
            notes.append(str(exc))
    if "map" in images and SCAN in got:
        image, map_notes = make_map(got)
        notes += map_notes
        written.append(write(out / "map.png", image))
    for note in notes:
        print(f"{PROG}: {note}", file=sys.stderr)
    for path in written:
        print(path)
    return 0 if written else EXIT_USAGE


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser(PROG, "write the panorama and a top-down map of the merged scan as PNGs")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder for panorama.png and map.png")
    parser.add_argument(
        "--timeout",
        type=number(float),
        default=DEFAULT_TIMEOUT_S,
        metavar="S",
        help=f"wait for the data (default {DEFAULT_TIMEOUT_S:g} s)",
    )
    parser.add_argument("--panorama", action="store_true", help="write the panorama (default: both images)")
    parser.add_argument("--map", action="store_true", help="write the map (default: both images)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot snapshot`."""
    return run_client(
        build_parser(),
        argv,
        lambda args, node, stop: snapshot(
            node, stop, args.out, [name for name in NEEDS if getattr(args, name)] or list(NEEDS), args.timeout
        ),
    )


if __name__ == "__main__":
    sys.exit(main())
