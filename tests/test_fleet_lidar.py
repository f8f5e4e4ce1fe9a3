"""Robots see each other: each lidar is blind to its own robot only (issue 17, item 3).

Two "mast" robots of the test's own (a dynamic 0.5 m cube standing on the floor, a 360° lidar
0.10 m in front of its face, 0.30 m above the floor: half its rays cross its own body) face each
other 3 m apart. Either lidar sits 0.35 m from its own cube's centre, the other cube's near face
0.25 m from that one's centre, so the face is 3 − 0.35 − 0.25 = 2.40 m ahead of the lidar.
A ray at angle θ hits that face where |2.40 · tan θ| ≤ 0.25 and then reads 2.40 / cos θ; every
other ray reads +inf, the own cube behind the lidar included (nothing else stands within 10 m:
the server's tug is spawned 15 m away). Ranges are quantised to 0.01 m: ±0.006 m; the rays that
graze the cube's edges (within two ray increments) are left out.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO
from server_helpers import running_server

SCAN = "sensor_msgs/msg/LaserScan"
SAMPLES = 720
HALF_SIZE, LIDAR_X, LIDAR_Z, APART = 0.25, 0.35, 0.30, 3.0
GAP = APART - HALF_SIZE - LIDAR_X  # 2.40 m from a lidar to the other cube's face
TOLERANCE = 0.006
FAR_AWAY = ("--spawn", "0", "-15", "0.1", "0", "--camera-size", "8x6", "--camera-rate", "1")


def _mast(name: str, x: float, yaw: float) -> str:
    size = 2 * HALF_SIZE
    box = f"<geometry><box><size>{size} {size} {size}</size></box></geometry>"
    return f"""
    <model name="{name}">
      <pose>{x} 0 {HALF_SIZE} 0 0 {yaw}</pose>
      <link name="body">
        <inertial><mass>10</mass><inertia><ixx>0.42</ixx><iyy>0.42</iyy><izz>0.42</izz></inertia></inertial>
        <collision name="collision">{box}</collision>
        <visual name="visual">{box}</visual>
        <sensor name="lidar" type="gpu_lidar">
          <pose>{LIDAR_X} 0 {LIDAR_Z - HALF_SIZE} 0 0 0</pose>
          <topic>{name}/scan</topic>
          <update_rate>5</update_rate>
          <lidar>
            <scan><horizontal><samples>{SAMPLES}</samples><min_angle>{-math.pi}</min_angle><max_angle>{math.pi}</max_angle></horizontal></scan>
            <range><min>0.08</min><max>10.0</max><resolution>0.01</resolution></range>
          </lidar>
        </sensor>
      </link>
    </model>"""


def _world(tmp: Path) -> Path:
    ground = (REPO / "worlds" / "empty.sdf").read_text()
    path = tmp / "two_masts.sdf"
    path.write_text(
        ground.replace("</world>", _mast("mast_a", 0.0, 0.0) + _mast("mast_b", APART, math.pi) + "</world>")
    )
    return path


def _expected() -> tuple[np.ndarray, np.ndarray]:
    """(ranges, which rays to compare) from the geometry in the module docstring."""
    angles = np.linspace(-math.pi, math.pi, SAMPLES)
    edge = math.atan(HALF_SIZE / GAP)
    increment = 2 * math.pi / (SAMPLES - 1)
    hits = np.abs(angles) <= edge
    ranges = np.where(hits, GAP / np.cos(angles), np.inf)
    return ranges, np.abs(np.abs(angles) - edge) > 2 * increment


def test_each_lidar_sees_the_other_robot_and_never_its_own(tmp_path: Path) -> None:
    """Both masts' scans: the other at 2.40 / cos θ across its face, +inf everywhere else, own body included."""
    with running_server(str(_world(tmp_path)), extra=FAR_AWAY, world_name="empty") as sim:
        scans = {name: sim.subscribe(f"{name}/scan", SCAN) for name in ("mast_a", "mast_b")}
        sim.prime(*scans.values())
        expected, compared = _expected()
        for name, scan in scans.items():
            ranges = np.asarray(scan.messages()[-1].ranges, dtype=float)
            assert ranges.size == SAMPLES
            seen = np.isfinite(ranges[compared])
            assert np.array_equal(seen, np.isfinite(expected[compared])), (
                f"{name}: returns at {np.degrees(np.linspace(-math.pi, math.pi, SAMPLES)[compared][seen]).round(1)}°"
            )
            assert ranges[compared][seen] == pytest.approx(expected[compared][seen], abs=TOLERANCE), name
            print(
                f"\n{name}: the other robot at {ranges[SAMPLES // 2]:.3f} m (expected {GAP:.3f}), {seen.sum()} rays on it"
            )
