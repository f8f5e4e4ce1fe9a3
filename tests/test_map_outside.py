"""The published map against the tug's own lidars: checked from outside, as a SLAM user would.

A lockstep server runs the warehouse; the tug drives an arc through it for DRIVE_S seconds. Every
scan of both lidars (5 Hz) is placed by the ground truth at its stamp (`model/flexley_tug/pose`,
the sensors' poses in the robot from urdf/flexley_tug.sdf) and marked into a grid the size of the
`map` message by plain ray marching: the cells along each ray free up to one cell short of its
end, the cell a quarter cell past a hit occupied. On the cells the scans observed, the map from the
bus and the scans' grid agree on at least 95 %, and their occupied cells overlap with an IoU of at
least 0.8. What they may differ on: the trolley (a moving model, not in the map), rays grazing
a face along a cell, and the tug's roll and pitch on its tyres (the beam is not exactly level).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
from conftest import ROBOT_SDF
from server_helpers import POSE_STAMPED, pose_of, running_server, stamp_ns

from simbot.description import load_model
from simbot.description.poses import Pose
from simbot.mapping.occupancy import LIDAR_HEIGHT
from simbot.transform import quaternion_to_matrix

LASER_SCAN = "sensor_msgs/msg/LaserScan"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
CHEAP_CAMERAS = ("--camera-size", "8x6", "--camera-rate", "1")
SCAN_NS = 200_000_000
STEP_NS = 1_000_000
SETTLE_STEPS = 500
DRIVE_S = 6.0
FORWARD, TURN = 0.5, 0.4
"""m/s and rad/s: an arc of 1.25 m radius from the spawn point, clear of the trolley."""
AGREEMENT, IOU = 0.95, 0.8
SPAWN = (-2.5, 0.0)
"""simbot-server's default spawn point."""


def _sensors() -> dict[str, Pose]:
    """Each lidar's pose in base_footprint (the robot's model frame), from the robot's description."""
    robot = load_model(ROBOT_SDF)
    return {s.name: link.pose @ s.pose for link, s in robot.sensors() if s.name in ("lidar_front", "lidar_back")}


def _mark(
    hits: npt.NDArray[np.int64], seen: npt.NDArray[np.int64], scan: Any, sensor: npt.NDArray[np.float64], info: Any
) -> None:
    """Ray marching of one scan from `sensor` (4 × 4 world pose) into counts of hits and passes."""
    res, ox, oy = info.resolution, info.origin.position.x, info.origin.position.y
    angles = scan.angle_min + scan.angle_increment * np.arange(len(scan.ranges))
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    hit = np.isfinite(ranges) & (ranges <= scan.range_max)
    reach = np.where(hit, ranges, scan.range_max)
    local = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    world = (sensor[:3, :3][None] * local[:, None, :]).sum(axis=-1)  # each ray's direction in the world
    heading = world[:, :2] / np.hypot(world[:, 0], world[:, 1])[:, None]
    origin = sensor[:2, 3]

    def cells(points: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        cols, rows = np.floor((points[:, 0] - ox) / res).astype(int), np.floor((points[:, 1] - oy) / res).astype(int)
        keep = (rows >= 0) & (rows < info.height) & (cols >= 0) & (cols < info.width)
        return rows[keep], cols[keep]

    steps = np.arange(0.0, scan.range_max, res / 2)
    along = steps[None, :] < (reach - np.where(hit, res, 0.0))[:, None]
    ray, step = np.nonzero(along)
    np.add.at(seen, cells(origin + heading[ray] * steps[step, None]), 1)
    np.add.at(hits, cells(origin + heading[hit] * (ranges[hit] + res / 4)[:, None]), 1)


def test_the_published_map_agrees_with_what_the_lidars_see() -> None:
    sensors = _sensors()
    with running_server("warehouse", extra=CHEAP_CAMERAS) as sim:
        maps = sim.subscribe("map", OCCUPANCY_GRID, latched=True)
        scans = {name: sim.subscribe(name, LASER_SCAN) for name in sensors}
        truth = sim.subscribe("model/flexley_tug/pose", POSE_STAMPED)
        sim.step(SETTLE_STEPS)
        grid = maps.wait_for(len, timeout=30.0, what="the map")[-1]
        assert grid.header.frame_id == "map"
        info = grid.info
        occupied = np.asarray(grid.data, dtype=np.int8).reshape(info.height, info.width) == 100
        hits, seen = np.zeros(occupied.shape, dtype=np.int64), np.zeros(occupied.shape, dtype=np.int64)
        sim.drive(FORWARD, TURN)
        start = round(sim.state()["sim_time"] * 1e9)
        for k in range(1, round(DRIVE_S * 1e9 / SCAN_NS) + 1):
            target = (start // SCAN_NS + k) * SCAN_NS
            sim.step((target - round(sim.state()["sim_time"] * 1e9)) // STEP_NS)
            (x, y, z), quat = pose_of(truth.wait_stamp(target, what="ground-truth pose").pose)
            robot = np.eye(4)
            robot[:3, :3], robot[:3, 3] = quaternion_to_matrix(quat), (x, y, z)
            for name, collector in scans.items():
                scan = collector.wait_stamp(target, timeout=10.0, what=name)
                assert stamp_ns(scan) == target
                sensor = robot @ sensors[name].matrix()
                assert abs(sensor[2, 3] - LIDAR_HEIGHT) < 0.005, "the map's default height is the beams'"
                _mark(hits, seen, scan, sensor, info)
    assert math.hypot(x - SPAWN[0], y - SPAWN[1]) > 1.0, "the tug drove through the warehouse"
    observed = (hits > 0) | (seen > 0)
    scanned = hits > 0
    agreement = float((scanned[observed] == occupied[observed]).mean())
    both, either = (scanned & occupied & observed).sum(), ((scanned | occupied) & observed).sum()
    assert observed.sum() > 20_000, "the scans saw much of the warehouse"
    assert agreement >= AGREEMENT, f"the map and the scans agree on {agreement:.1%} of {observed.sum()} cells"
    assert both / either >= IOU, f"occupied cells' IoU {both / either:.3f} ({both} of {either})"
