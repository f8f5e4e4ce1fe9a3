"""Benchmark of localisation on simbot's data (issue 55's outside check): Nav2's AMCL (the PyPI package
`amcl`, nav2_amcl's particle filter and differential motion model) on the dynamic tug's scans and
wheel odometry, with simbot's tyre and with the knife-edge it replaced, in one run.

The warehouse runs in lockstep in this process (its systems on a local node, as simbot.gym.local
runs a world), the tug at its spawn pose; the docking trolley is left out, as bench_turn leaves it,
because it stands where the loop turns. The tug drives a 25.15 m loop at 0.5 m/s: the straight it
spawns on, joined to a parallel one 6 m to its left by half circles of 3 m radius (centres at
(-0.85, 3) and (-4.0, 3); the chassis' closest approach to the map's obstacles is in the table).
A pure-pursuit follower on the ground truth steers it, 20 times a second, 1 m ahead, so both tyres
drive the same loop (neither turns at the commanded rate: bench_turn). What is recorded is what a
user gets: both lidars' LaserScans, `odom` (DiffDrive's wheel odometry), tf_static's lidar poses,
and the ground truth at each scan and each `odom` message.

The map is `simbot map`'s, read back as Nav2's map_server reads map.yaml and map.pgm (trinary). AMCL
gets Nav2's default parameters (NAV2_DEFAULTS) and, as nav2_amcl does, a filter update on each
lidar's next scan once `odom` has moved 0.25 m along x or y or turned 0.2 rad since the last one;
each scan's bearings in base_footprint from tf_static (laser yaw folded into them, as nav2_amcl
does), readings at or below range_min as range_max; the odometry pose at the scan's stamp
(interpolated, as tf2 does); the initial pose the true start, with Nav2's initial covariance. Its
error is the mean pose after each update against the ground truth at that scan. Each filter runs
three times (its sampling differs) on each recording, with `odom` and with the true pose as
odometry (the floor: what the scans and map allow). The knife-edge is restated as SDF's
force-dependent slip for the wheels' mean load (bench_turn.knife_edge).

    python benchmarks/bench_localisation.py

Where `amcl` cannot be imported (`pip install -e '.[localisation]'`), one line says so and the page
is left as it is.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from bench_turn import knife_edge
from nav2_map import Map, closest_approach, simbot_warehouse_map
from tables import cpu_model, publish

from simbot.bus import messages
from simbot.bus.local import LocalNode
from simbot.description import load_world
from simbot.description.model import Model
from simbot.description.resources import asset
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world import SimWorld, load_robot
from simbot.sim.physics.steady_turn import Chassis
from simbot.sim.server import ROBOT_NAME, ServerConfig, robot_places
from simbot.transform import quaternion_to_matrix, yaw_of

SPEED, RADIUS = 0.5, 3.0
"""m/s and m: the loop's speed and its half circles' radius."""
START = (-2.5, 0.0)
"""The spawn point (heading +x), on the loop's first straight."""
RIGHT_CENTRE, LEFT_CENTRE = (-0.85, 3.0), (-4.0, 3.0)
"""The half circles' centres: straights of 3.15 m, so that the loop is 25.15 m, as issue 55's."""
LOOKAHEAD = 1.0
"""m: the pure-pursuit point ahead on the loop."""
CONTROL_STEPS = 50
"""Physics steps (1 ms) between commands: 20 Hz, Nav2's controller frequency."""
RAMP = 1.0
"""s to reach SPEED from rest."""
SETTLE_STEPS = 500
"""Steps standing still before the drive, the tug settling on its tyres."""
RUNS = 3
"""AMCL runs on each recording and odometry."""
LASERS = ("lidar_front", "lidar_back")
CHASSIS = (2.1, 0.5)
"""m: the chassis box's length and width (urdf/flexley_tug.sdf), for the clearance check."""

NAV2_DEFAULTS: dict[str, Any] = {
    "min_particles": 500,
    "max_particles": 2000,
    "recovery_alpha_slow": 0.0,
    "recovery_alpha_fast": 0.0,
    "alpha1": 0.2,
    "alpha2": 0.2,
    "alpha3": 0.2,
    "alpha4": 0.2,
    "alpha5": 0.2,
    "z_hit": 0.5,
    "z_short": 0.05,
    "z_max": 0.05,
    "z_rand": 0.5,
    "sigma_hit": 0.2,
    "lambda_short": 0.1,
    "max_beams": 60,
    "update_min_d": 0.25,
    "update_min_a": 0.2,
    "laser_max_range": 100.0,
    "laser_min_range": -1.0,
    "robot_model_type": "differential",
    "init_cov": (0.5 * 0.5, 0.5 * 0.5, (math.pi / 12) ** 2),
}
"""nav2_amcl's parameter defaults, as far as the `amcl` package takes them (its laser model is the beam
model, its pf_err/pf_z its own)."""

Pose2 = tuple[float, float, float]
"""x, y, yaw."""


@dataclass(frozen=True)
class Scan:
    stamp_ns: int
    frame: str
    ranges: npt.NDArray[np.float64]
    angle_min: float
    increment: float
    range_min: float
    range_max: float
    truth: Pose2


@dataclass
class Recording:
    scans: list[Scan] = field(default_factory=list)
    odom: list[tuple[int, Pose2]] = field(default_factory=list)
    lasers: dict[str, Pose2] = field(default_factory=dict)
    """Each scan frame's pose in base_footprint, from tf_static."""
    truth: list[Pose2] = field(default_factory=list)
    """The ground truth at each `odom` message."""

    def odom_at(self, stamp_ns: int) -> Pose2:
        """`odom`'s pose at `stamp_ns`, interpolated between the messages around it (tf2's lookup)."""
        stamps = [s for s, _ in self.odom]
        i = bisect.bisect_left(stamps, stamp_ns)
        if i < len(stamps) and stamps[i] == stamp_ns:
            return self.odom[i][1]
        if i == 0 or i == len(stamps):
            raise ValueError(f"no odom around {stamp_ns} ns")
        (t0, a), (t1, b) = self.odom[i - 1], self.odom[i]
        f = (stamp_ns - t0) / (t1 - t0)
        return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * math.remainder(b[2] - a[2], math.tau))


# The loop


def loop_length() -> float:
    straight = RIGHT_CENTRE[0] - LEFT_CENTRE[0]
    return 2 * straight + 2 * math.pi * RADIUS


def loop_point(s: float) -> tuple[float, float]:
    """The point `s` metres along the loop from START (taken round and round)."""
    s %= loop_length()
    (rx, cy), (lx, _) = RIGHT_CENTRE, LEFT_CENTRE
    legs: list[tuple[float, Callable[[float], tuple[float, float]]]] = [
        (rx - START[0], lambda d: (START[0] + d, cy - RADIUS)),
        (math.pi * RADIUS, lambda d: (rx + RADIUS * math.sin(d / RADIUS), cy - RADIUS * math.cos(d / RADIUS))),
        (rx - lx, lambda d: (rx - d, cy + RADIUS)),
        (math.pi * RADIUS, lambda d: (lx - RADIUS * math.sin(d / RADIUS), cy + RADIUS * math.cos(d / RADIUS))),
        (START[0] - lx, lambda d: (lx + d, cy - RADIUS)),
    ]
    for length, at in legs:
        if s <= length:
            return at(s)
        s -= length
    return START


class PurePursuit:
    """Steers the tug's base_footprint along the loop from its ground truth; `s` is its progress."""

    def __init__(self) -> None:
        self.s = 0.0

    def command(self, pose: Pose2, elapsed: float) -> tuple[float, float]:
        x, y, yaw = pose
        ahead = np.arange(self.s, self.s + 1.0, 0.005)
        points = np.array([loop_point(s) for s in ahead])
        self.s = float(ahead[int(np.argmin(np.hypot(points[:, 0] - x, points[:, 1] - y)))])
        gx, gy = loop_point(self.s + LOOKAHEAD)
        dx, dy = gx - x, gy - y
        lx, ly = math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy
        speed = SPEED * min(1.0, elapsed / RAMP)
        return speed, speed * 2 * ly / (lx * lx + ly * ly)


# The run


def _pose2(transform: Any) -> Pose2:
    (x, y, _), quat = transform
    return float(x), float(y), yaw_of(quat)


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _frame_poses(tf_static: Any, frames: Sequence[str], root: str = "base_footprint") -> dict[str, Pose2]:
    """Each of `frames` in `root`, composed along tf_static's tree."""
    parents = {}
    for t in tf_static.transforms:
        tr, q = t.transform.translation, t.transform.rotation
        matrix = np.eye(4)
        matrix[:3, :3] = quaternion_to_matrix((q.x, q.y, q.z, q.w))
        matrix[:3, 3] = (tr.x, tr.y, tr.z)
        parents[t.child_frame_id] = (t.header.frame_id, matrix)
    poses = {}
    for frame in frames:
        at, name = np.eye(4), frame
        while name != root:
            parent, matrix = parents[name]
            at, name = matrix @ at, parent
        poses[frame] = (float(at[0, 3]), float(at[1, 3]), math.atan2(at[1, 0], at[0, 0]))
    return poses


def record(robot: Model) -> tuple[Recording, float]:
    """The loop driven by `robot` in the warehouse; the wall seconds it took."""
    config = ServerConfig(asset("worlds/warehouse.sdf"), asset("urdf/flexley_tug.sdf"), mode=Mode.LOCKSTEP)
    world = load_world(config.world)
    world = dataclasses.replace(world, models=tuple(m for m in world.models if m.name != "trolley"))
    node = LocalNode()
    sim_world = SimWorld(
        world, robot, robot_places(config.spawn, 0), SimBus(node), config.seed, config.run_options(), config.mode
    )
    physics, sim = sim_world.physics, sim_world.sim
    rec = Recording()
    tf_static: list[Any] = []

    def scanned(msg: Any) -> None:
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        truth = _pose2(physics.model_pose(ROBOT_NAME))
        rec.scans.append(
            Scan(
                _stamp(msg.header), msg.header.frame_id, ranges, msg.angle_min, msg.angle_increment,
                msg.range_min, msg.range_max, truth,
            )
        )  # fmt: skip

    def odometry(msg: Any) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        rec.odom.append((_stamp(msg.header), (p.x, p.y, yaw_of((q.x, q.y, q.z, q.w)))))
        rec.truth.append(_pose2(physics.model_pose(ROBOT_NAME)))

    subscriptions = [
        *(node.subscribe(topic, "sensor_msgs/msg/LaserScan", scanned) for topic in LASERS),
        node.subscribe("odom", "nav_msgs/msg/Odometry", odometry),
        node.subscribe("tf_static", "tf2_msgs/msg/TFMessage", tf_static.append),
    ]
    cmd_vel = node.publisher("cmd_vel", messages.Twist)
    follower, total = PurePursuit(), loop_length()
    started = time.perf_counter()
    try:
        for _ in range(SETTLE_STEPS):
            sim.step()
        rec.scans.clear()
        drive_start, step = sim.clock.now_ns, 0
        while follower.s < total - 0.01:
            if step % CONTROL_STEPS == 0:
                pose = _pose2(physics.model_pose(ROBOT_NAME))
                speed, turn = follower.command(pose, (sim.clock.now_ns - drive_start) / 1e9)
                if follower.s >= total - 0.01:
                    break
                cmd_vel.put(messages.twist((speed, 0.0, 0.0), (0.0, 0.0, turn)))
            sim.step()
            step += 1
            if step > 120_000:
                raise RuntimeError(f"the loop did not close in 120 s (at {follower.s:.2f} of {total:.2f} m)")
        frames = sorted({scan.frame for scan in rec.scans})
        rec.lasers = _frame_poses(tf_static[-1], frames)
    finally:
        for subscription in subscriptions:
            subscription.close()
        sim_world.close()
    return rec, time.perf_counter() - started


def returns_on_map(grid: Map, rec: Recording) -> float:
    """The share of returns that, placed by the ground truth and tf_static, land on or next to an
    occupied cell (the issue's check that lidar, map and tf agree)."""
    near = cv2.dilate((grid.cells == 100).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    hits = total = 0
    for scan in rec.scans:
        lx, ly, lyaw = rec.lasers[scan.frame]
        x, y, yaw = scan.truth
        returned = np.isfinite(scan.ranges)
        r = scan.ranges[returned]
        bearing = yaw + lyaw + scan.angle_min + scan.increment * np.flatnonzero(returned)
        ox, oy = x + math.cos(yaw) * lx - math.sin(yaw) * ly, y + math.sin(yaw) * lx + math.cos(yaw) * ly
        cols = np.floor((ox + r * np.cos(bearing) - grid.origin[0]) / grid.resolution).astype(int)
        rows = np.floor((oy + r * np.sin(bearing) - grid.origin[1]) / grid.resolution).astype(int)
        inside = (rows >= 0) & (rows < near.shape[0]) & (cols >= 0) & (cols < near.shape[1])
        hits += int(near[rows[inside], cols[inside]].sum())
        total += r.size
    return hits / total


# AMCL


@dataclass(frozen=True)
class Errors:
    position: list[float]
    heading: list[float]
    """radians, absolute."""


def localise(amcl: Any, grid: Any, rec: Recording, truth_odometry: bool) -> Errors:
    """One AMCL run over the recording, as nav2_amcl's laserReceived feeds its filter."""
    p = NAV2_DEFAULTS
    motion = amcl.MotionParameters(p["alpha1"], p["alpha2"], p["alpha3"], p["alpha4"], p["alpha5"])
    laser = amcl.LaserParameters(
        p["z_hit"], p["z_short"], p["z_max"], p["z_rand"], p["sigma_hit"], p["lambda_short"], 0.0, p["max_beams"]
    )
    pf = amcl.AMCL(
        p["min_particles"], p["max_particles"], p["recovery_alpha_slow"], p["recovery_alpha_fast"],
        motion, laser, p["robot_model_type"],
    )  # fmt: skip
    pf.set_map(grid)
    covariance = amcl.Matrix3D()
    for i, variance in enumerate(p["init_cov"]):
        covariance.set(i, i, variance)
    pf.set_initial_pose(amcl.Vector3D(*rec.scans[0].truth), covariance)
    pending: set[str] = set()
    last: Pose2 | None = None
    errors = Errors([], [])
    for scan in rec.scans:
        odom = scan.truth if truth_odometry else rec.odom_at(scan.stamp_ns)
        if last is None or (
            abs(odom[0] - last[0]) > p["update_min_d"]
            or abs(odom[1] - last[1]) > p["update_min_d"]
            or abs(math.remainder(odom[2] - last[2], math.tau)) > p["update_min_a"]
        ):
            pending = set(rec.lasers)
        if scan.frame not in pending:
            continue
        pending.discard(scan.frame)
        lx, ly, lyaw = rec.lasers[scan.frame]
        pf.set_laser_pose(amcl.Vector3D(lx, ly, 0.0))
        range_max = min(scan.range_max, p["laser_max_range"]) if p["laser_max_range"] > 0 else scan.range_max
        range_min = max(scan.range_min, p["laser_min_range"])
        ranges = np.where(scan.ranges <= range_min, range_max, scan.ranges)
        bearings = math.remainder(lyaw + scan.angle_min, math.tau) + scan.increment * np.arange(ranges.size)
        pf.update(
            amcl.create_laser_scan_from_list(np.stack([ranges, bearings], 1).tolist(), range_max), amcl.Vector3D(*odom)
        )
        last = odom
        estimate = pf.get_pose_mean()
        x, y, yaw = scan.truth
        errors.position.append(math.hypot(estimate.x - x, estimate.y - y))
        errors.heading.append(abs(math.remainder(estimate.theta - yaw, math.tau)))
    return errors


def drift(rec: Recording) -> tuple[float, float]:
    """`odom`'s position (m) and heading (rad) error when the loop closed, the start's ground truth its origin."""
    x, y, yaw = rec.truth[-1]
    x0, y0, yaw0 = rec.scans[0].truth
    ox0, oy0, oyaw0 = rec.odom_at(rec.scans[0].stamp_ns)
    ox, oy, oyaw = rec.odom[-1][1]

    def local(px: float, py: float, bx: float, by: float, byaw: float) -> tuple[float, float]:
        dx, dy = px - bx, py - by
        return math.cos(byaw) * dx + math.sin(byaw) * dy, -math.sin(byaw) * dx + math.cos(byaw) * dy

    true_local, odom_local = local(x, y, x0, y0, yaw0), local(ox, oy, ox0, oy0, oyaw0)
    turn_error = math.remainder((oyaw - oyaw0) - (yaw - yaw0), math.tau)
    return math.dist(true_local, odom_local), abs(turn_error)


def summary(runs: Sequence[Errors]) -> dict[str, float]:
    medians = [statistics.median(r.position) for r in runs]
    headings = [statistics.median(r.heading) for r in runs]
    return {
        "median": statistics.median(medians),
        "median_lo": min(medians),
        "median_hi": max(medians),
        "max": max(max(r.position) for r in runs),
        "heading": math.degrees(statistics.median(headings)),
        "heading_max": math.degrees(max(max(r.heading) for r in runs)),
        "updates": statistics.median(len(r.position) for r in runs),
    }


def main() -> None:
    try:
        import amcl
    except ImportError:
        print("bench_localisation: the `amcl` package (Nav2's AMCL) is not installed: pip install -e '.[localisation]'")
        return
    started = time.perf_counter()
    grid = simbot_warehouse_map()
    amcl_grid = amcl.create_occupancy_grid_from_list(grid.cells.astype(int).tolist(), grid.resolution, *grid.origin)
    model = load_robot(asset("urdf/flexley_tug.sdf"))
    load = float(Chassis.of(model).loads().mean())
    columns: dict[str, dict[str, float]] = {}
    for name, robot in (("tyre", model), ("edge", knife_edge(model, load))):
        rec, wall = record(robot)
        odom_runs = [localise(amcl, amcl_grid, rec, truth_odometry=False) for _ in range(RUNS)]
        truth_runs = [localise(amcl, amcl_grid, rec, truth_odometry=True) for _ in range(RUNS)]
        metres, radians = drift(rec)
        columns[name] = {
            **{f"odom_{k}": v for k, v in summary(odom_runs).items()},
            **{f"truth_{k}": v for k, v in summary(truth_runs).items()},
            "drift": metres,
            "drift_deg": math.degrees(radians),
            "sim_s": (rec.odom[-1][0] - rec.scans[0].stamp_ns) / 1e9,
            "wall_s": wall,
            "on_map": returns_on_map(grid, rec),
            "clearance": closest_approach(grid, rec.truth, CHASSIS),
        }
        print(f"{name}: {columns[name]}", file=sys.stderr)
    tyre, edge = columns["tyre"], columns["edge"]

    def median(prefix: str) -> Callable[[dict[str, float]], str]:
        return lambda c: f"{c[prefix + 'median']:.3f} ({c[prefix + 'median_lo']:.3f}–{c[prefix + 'median_hi']:.3f})"

    rows: list[tuple[str, Callable[[dict[str, float]], str], str]] = [
        ("AMCL on `odom`: position error, median (of three runs: their range), m", median("odom_"), "0.35–0.40"),
        ("AMCL on `odom`: position error, most, m", lambda c: f"{c['odom_max']:.3f}", "0.62"),
        ("AMCL on `odom`: heading error, median / most, °", lambda c: f"{c['odom_heading']:.2f} / {c['odom_heading_max']:.2f}", "–"),
        ("AMCL on the true odometry (the floor): position error, median, m", median("truth_"), "0.03–0.04"),
        ("AMCL on the true odometry: position error, most, m", lambda c: f"{c['truth_max']:.3f}", "–"),
        ("AMCL on the true odometry: heading error, median / most, °", lambda c: f"{c['truth_heading']:.2f} / {c['truth_heading_max']:.2f}", "–"),
        ("`odom`'s drift when the loop closes: position, m / heading, °", lambda c: f"{c['drift']:.2f} / {c['drift_deg']:.1f}", "7.1 / 41"),
        ("filter updates a run (both lidars)", lambda c: f"{c['odom_updates']:.0f}", "–"),
        ("returns placed by the ground truth on or next to an occupied cell", lambda c: f"{c['on_map']:.1%}", "99 %"),
        ("the chassis' closest approach to the map's obstacles, m", lambda c: f"{c['clearance']:.2f}", "–"),
        ("the loop's sim time, s / wall time, s", lambda c: f"{c['sim_s']:.1f} / {c['wall_s']:.0f}", "–"),
    ]  # fmt: skip
    table = [
        "| the tug's 25.15 m loop in the warehouse at 0.5 m/s, Nav2's AMCL | simbot's tyre | the knife-edge "
        "(before) | issue 55's before |",
        "| --- | --- | --- | --- |",
        *(f"| {label} | {cell(tyre)} | {cell(edge)} | {before} |" for label, cell, before in rows),
    ]
    publish("localisation", table)
    print(f"({cpu_model()}, {time.perf_counter() - started:.0f} s in all)")


if __name__ == "__main__":
    main()
