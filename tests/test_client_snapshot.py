"""simbot snapshot: a real snapshot process on a real bus writes PNGs whose pixels sit where the geometry says.

For exact geometry the data come from a test node in the server role: a synthetic merged scan (a
wall 2 m ahead), a synthetic panorama, a URDF whose chassis is not SPEC's (so the footprint must be
read from the bus), and model poses that put the trolley at a known place and angle relative to a
robot that is itself turned. One more test runs the real chain: server, merger, stitcher.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
import numpy.typing as npt
from bus_helpers import endpoint, free_port, unique_namespace
from client_helpers import client_process
from server_helpers import REPO, running_server

from simbot.bus import BusOptions, Node, messages
from simbot.clients import snapshot as snap

RES = snap.RESOLUTION_M
CENTRE = snap.MapView().size // 2
PERIOD_S = 0.05
STAMP_NS = 5_000_000_000
WALL_X_M, WALL_HALF_M = 2.0, 1.0
CHASSIS_M = (1.6, 0.8)
"""The synthetic robot's chassis, deliberately not SPEC's 2.1 × 0.5."""
ROBOT_POSE = (3.0, -1.0, math.pi / 2)
TROLLEY_IN_ROBOT = (-2.5, 2.0, 0.5)
"""Where the synthetic trolley is in the robot's frame (x, y, yaw)."""
EDGE_PX = 2
SNAPSHOT = (sys.executable, "-m", "simbot.clients.snapshot")
EVERYTHING = (snap.SCAN, snap.PANORAMA, snap.DESCRIPTION, snap.ROBOT_POSE, snap.TROLLEY_POSE)
"""Slack for a polygon's 2-px outline and rounding to pixels."""

URDF = f"""<?xml version="1.0"?>
<robot name="small">
  <link name="base_footprint"/>
  <link name="base_link">
    <collision><geometry><box size="{CHASSIS_M[0]} {CHASSIS_M[1]} 0.2"/></geometry></collision>
  </link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/></joint>
</robot>
"""


def wall_scan() -> Any:
    """A 360° scan in base_link that sees a wall across x = 2 m for |y| ≤ 1 m and nothing else."""
    count = 720
    increment = 2 * math.pi / count
    angles = -math.pi + increment * np.arange(count)
    with np.errstate(divide="ignore"):
        ranges = WALL_X_M / np.cos(angles)
    hits = (np.cos(angles) > 0) & (np.abs(WALL_X_M * np.tan(angles)) <= WALL_HALF_M)
    ranges = np.where(hits, ranges, np.inf)
    angles_msg = (-math.pi, math.pi - increment, increment)
    return messages.laser_scan(STAMP_NS, "base_link", angles_msg, (0.0, 0.2), (0.08, 10.0), ranges)


def panorama_rgb() -> npt.NDArray[np.uint8]:
    """64 × 24 rgb8: red left half, blue right half, a green top row: any channel mix-up shows."""
    pixels = np.zeros((24, 64, 3), dtype=np.uint8)
    pixels[:, :32, 0] = 255
    pixels[:, 32:, 2] = 255
    pixels[0, :, 1] = 255
    return pixels


def pose(x: float, y: float, yaw: float) -> Any:
    return messages.pose_stamped(STAMP_NS, "world", (x, y, 0.1), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))


def trolley_world() -> tuple[float, float, float]:
    """The trolley's world pose that puts it at TROLLEY_IN_ROBOT."""
    xr, yr, yaw = ROBOT_POSE
    x, y, rel_yaw = TROLLEY_IN_ROBOT
    return xr + math.cos(yaw) * x - math.sin(yaw) * y, yr + math.sin(yaw) * x + math.cos(yaw) * y, yaw + rel_yaw


@contextmanager
def synthetic_bus(topics: Sequence[str]) -> Iterator[tuple[int, str]]:
    """A server-role node that publishes `topics` (robot_description latched) every 50 ms; yields (port, namespace)."""
    port, namespace = free_port(), unique_namespace()
    data = {
        snap.SCAN: wall_scan(),
        snap.PANORAMA: messages.image(STAMP_NS, "camera_360", panorama_rgb()),
        snap.ROBOT_POSE: pose(*ROBOT_POSE),
        snap.TROLLEY_POSE: pose(*trolley_world()),
    }
    stop = threading.Event()
    with Node(BusOptions(listen=(endpoint(port),), namespace=namespace), "server") as node:
        if snap.DESCRIPTION in topics:
            node.publisher(snap.DESCRIPTION, messages.String, latched=True).put(messages.string(URDF))
        publishers = {topic: node.publisher(topic, data[topic].__msgtype__) for topic in topics if topic in data}

        def feed() -> None:
            while not stop.wait(PERIOD_S):
                for topic, publisher in publishers.items():
                    publisher.put(data[topic])

        thread = threading.Thread(target=feed, daemon=True)
        thread.start()
        try:
            yield port, namespace
        finally:
            stop.set()
            thread.join()


def run_snapshot(port: int, namespace: str, out: Path, *args: str) -> subprocess.CompletedProcess[str]:
    command = [*SNAPSHOT, "--connect", endpoint(port), "--namespace", namespace, "--out", str(out), *args]
    return subprocess.run(command, check=False, capture_output=True, text=True, cwd=REPO, timeout=60)


def read_png(path: Path, flags: int = cv2.IMREAD_COLOR) -> npt.NDArray[np.uint8]:
    """The 8-bit image OpenCV reads at `path` (cv2.imread's default: BGR)."""
    image = cv2.imread(str(path), flags)
    assert image is not None, f"OpenCV reads no image at {path}"
    return cast(npt.NDArray[np.uint8], image)


def mask(image: npt.NDArray[np.uint8], *colours: tuple[int, int, int]) -> npt.NDArray[np.bool_]:
    """Pixels of exactly one of `colours` (BGR)."""
    return np.any([np.all(image == colour, axis=2) for colour in colours], axis=0)


def bbox(pixels: npt.NDArray[np.bool_]) -> tuple[int, int, int, int]:
    """(first row, last row, first column, last column) of the true pixels."""
    rows, cols = np.nonzero(pixels)
    assert rows.size, "no pixels of that colour"
    return int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())


def assert_footprint(image: npt.NDArray[np.uint8], length: float, width: float) -> None:
    """The robot's box is centred on the map's centre, `length` up the image, `width` across."""
    top, bottom, left, right = bbox(mask(image, snap.ROBOT_FILL, snap.ROBOT_EDGE))
    half_rows, half_cols = length / 2 / RES, width / 2 / RES
    assert abs(top - (CENTRE - half_rows)) <= EDGE_PX and abs(bottom - (CENTRE + half_rows)) <= EDGE_PX, (top, bottom)
    assert abs(left - (CENTRE - half_cols)) <= EDGE_PX and abs(right - (CENTRE + half_cols)) <= EDGE_PX, (left, right)


def test_map_and_panorama_show_the_published_geometry(tmp_path: Path) -> None:
    with synthetic_bus(EVERYTHING) as (port, namespace):
        result = run_snapshot(port, namespace, tmp_path / "out", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert result.stdout.split() == [str(tmp_path / "out" / "panorama.png"), str(tmp_path / "out" / "map.png")]

    panorama = read_png(tmp_path / "out" / "panorama.png", cv2.IMREAD_UNCHANGED)
    assert np.array_equal(panorama, panorama_rgb()[:, :, ::-1]), "the panorama is not the published image in BGR"

    image = read_png(tmp_path / "out" / "map.png")
    assert image.shape == (601, 601, 3)  # ±6 m at 2 cm/px, the robot at the centre pixel

    # the wall: every return 2 m ahead (row = centre − 2 m / 2 cm), spanning y = +1 … −1 m (left … right)
    rows, cols = np.nonzero(mask(image, snap.SCAN_POINTS))
    wall_row = CENTRE - WALL_X_M / RES
    assert rows.size > 0 and np.all(np.abs(rows - wall_row) <= 1.0), (rows.min(), rows.max())
    assert abs(float(np.mean(rows)) - wall_row) <= 0.5
    half_span = WALL_HALF_M / RES
    assert abs(cols.min() - (CENTRE - half_span)) <= EDGE_PX, cols.min()
    assert abs(cols.max() - (CENTRE + half_span)) <= EDGE_PX, cols.max()

    assert_footprint(image, *CHASSIS_M)

    # the trolley: a 1.4 m square turned 0.5 rad, centred 2.5 m behind and 2 m left of the robot
    x, y, yaw = TROLLEY_IN_ROBOT
    centre_row, centre_col = CENTRE - x / RES, CENTRE - y / RES
    top, bottom, left, right = bbox(mask(image, snap.TROLLEY))
    assert abs((top + bottom) / 2 - centre_row) <= 1, (top, bottom)
    assert abs((left + right) / 2 - centre_col) <= 1, (left, right)
    half = snap.TROLLEY_DECK_M / 2 * (abs(math.cos(yaw)) + abs(math.sin(yaw))) / RES  # 47.5 px: turned, not 35
    assert abs((bottom - top) / 2 - half) <= EDGE_PX, bottom - top
    assert abs((right - left) / 2 - half) <= EDGE_PX, right - left
    # turned left (counter-clockwise), its front-most corner (0.7, −0.7) lies right of its centre, at y = −0.28 m
    corner_y = 0.7 * math.sin(yaw) - 0.7 * math.cos(yaw)
    top_cols = np.nonzero(mask(image, snap.TROLLEY)[top])[0]
    assert abs(float(np.mean(top_cols)) - (centre_col - corner_y / RES)) <= EDGE_PX, top_cols


def test_silent_details_are_reported_and_the_map_still_written(tmp_path: Path) -> None:
    """No panorama, no trolley, no description: three lines, the map with SPEC's footprint, exit 0."""
    with synthetic_bus([snap.SCAN, snap.ROBOT_POSE]) as (port, namespace):
        result = run_snapshot(port, namespace, tmp_path, "--timeout", "3")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(tmp_path / "map.png")]
    assert not (tmp_path / "panorama.png").exists()
    lines = result.stderr.splitlines()
    assert len(lines) == 3, lines
    assert any(f"no {snap.PANORAMA} within" in line and "stitcher" in line for line in lines), lines
    assert any(f"no {snap.TROLLEY_POSE} within" in line for line in lines), lines
    assert any(f"no {snap.DESCRIPTION} within" in line and "2.1 × 0.5" in line for line in lines), lines
    image = read_png(tmp_path / "map.png")
    assert_footprint(image, *snap.SPEC_CHASSIS_M)
    assert not mask(image, snap.TROLLEY).any()


def test_nothing_on_the_bus_is_exit_2_naming_the_silent_keys(tmp_path: Path) -> None:
    with synthetic_bus([]) as (port, namespace):
        result = run_snapshot(port, namespace, tmp_path / "out", "--timeout", "1", "--panorama")
        not_a_folder = tmp_path / "file"
        not_a_folder.write_text("")
        bad_out = run_snapshot(port, namespace, not_a_folder, "--timeout", "1")
    assert result.returncode == 2 and result.stdout == ""
    silent = r"simbot snapshot: no camera_360/image_raw within [\d.]+ s: is the stitcher running\?\n"
    assert re.fullmatch(silent, result.stderr), result.stderr
    assert not any((tmp_path / "out").iterdir())
    assert bad_out.returncode == 2 and len(bad_out.stderr.splitlines()) == 1 and "--out" in bad_out.stderr, (
        bad_out.stderr
    )


def test_snapshot_of_the_real_merger_and_stitcher(tmp_path: Path) -> None:
    """The warehouse at spawn: the trolley 3.5 m ahead, 0.2 m left; its two near legs in the merged scan."""
    with (
        running_server("warehouse", extra=("--camera-size", "160x120")) as sim,
        client_process(sim, "merger"),
        client_process(sim, "stitcher"),
    ):
        panoramas = sim.subscribe(snap.PANORAMA, snap.TYPES[snap.PANORAMA])
        command = [
            *SNAPSHOT,
            "--connect",
            sim.endpoint,
            "--namespace",
            sim.namespace,
            "--out",
            str(tmp_path),
            "--timeout",
            "40",
        ]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
        deadline = time.monotonic() + 50
        while process.poll() is None and time.monotonic() < deadline:
            sim.step(50)  # lockstep: 50 ms of sim time at a time while the clients keep up on wall time
            time.sleep(0.05)
        _, stderr = process.communicate(timeout=10)
        robot, _ = sim.pose("flexley_tug")
        trolley, _ = sim.pose("trolley")
    assert process.returncode == 0, stderr
    assert stderr == "", stderr
    panorama = read_png(tmp_path / "panorama.png")
    published = [m for m in panoramas.messages() if (m.height, m.width) == panorama.shape[:2]]
    assert any(np.array_equal(panorama, snap.panorama_pixels(m)) for m in published), (
        "not one of the stitcher's panoramas"
    )

    image = read_png(tmp_path / "map.png")
    assert_footprint(image, 2.1, 0.5)  # from the real robot_description
    rel_x, rel_y = trolley[0] - robot[0], trolley[1] - robot[1]  # both unturned at spawn
    top, bottom, left, right = bbox(mask(image, snap.TROLLEY))
    assert (
        abs((top + bottom) / 2 - (CENTRE - rel_x / RES)) <= 1 and abs((left + right) / 2 - (CENTRE - rel_y / RES)) <= 1
    )
    scan = mask(image, snap.SCAN_POINTS)
    for leg_y in (
        0.65,
        -0.65,
    ):  # the rear legs (4 cm square at x −0.65) face the robot 0.67 m before the trolley's centre
        row, col = round(CENTRE - (rel_x - 0.67) / RES), round(CENTRE - (rel_y + leg_y) / RES)
        assert scan[row - 3 : row + 4, col - 3 : col + 4].any(), (
            f"no return within 6 cm of the leg at y {rel_y + leg_y:+.2f}"
        )
