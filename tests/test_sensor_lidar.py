"""The lidars of a real server in lockstep, against the geometry of a world of known boxes.

`tests/fixtures/lidar_boxes.sdf` stands static boxes 1 m tall around the origin; the robot is
spawned there, yaw 0, so its front lidar sits at x 0.99 and its back lidar at x −0.95 (0.26 m
above base_footprint, ~0.36 m above the floor). Each scan is checked ray by ray against a model:
the same rays cast analytically (3-D slab test) from the sensor's pose, computed from the
ground-truth pose published at the scan's stamp (both run on multiples of 20 ms). A range is
quantised to the 0.01 m resolution, so it is within 0.005 m of the true distance; the model's
pose (ground truth, float32 box positions, the tiny roll and pitch of the tyres) adds well under
1 mm: hence ±0.006 m. Rays that graze a box's edge (their verdict changes when the boxes grow or
shrink by 1 cm) are left out of the ray-by-ray comparison. No noise in the SDF: none to allow for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from conftest import REPO, ROBOT_SDF
from server_helpers import POSE_STAMPED, Collector, SimServer, pose_of, reset_before_each, running_server, stamp_ns

from simbot.description import load_model, load_world
from simbot.description.lidar_params import LidarParams
from simbot.description.poses import Pose
from simbot.sim.physics import Physics
from simbot.sim.systems.imu import ImuParams
from simbot.transform import quaternion_to_matrix

WORLD = REPO / "tests" / "fixtures" / "lidar_boxes.sdf"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
IMU = "sensor_msgs/msg/Imu"
# cameras (someone else's tests) made tiny and slow so that they cost nothing here
CHEAP_CAMERAS = ("--camera-size", "8x6", "--camera-rate", "1")
AT_ORIGIN = ("--spawn", "0", "0", "0.1", "0")

SAMPLES = 720
ANGLE_MAX = 1.396263
RANGE_MIN, RANGE_MAX, RESOLUTION = 0.08, 10.0, 0.01
TOLERANCE = RESOLUTION / 2 + 0.001  # quantisation + the model's pose (see the module docstring)
SCAN_NS = 200_000_000  # 5 Hz
STEP_NS = 1_000_000
SETTLE_STEPS = 500  # spawned 0.1 m up, the robot settles on its tyres (z 0.0955) first

# the sensors in base_footprint (SPEC §1): position, yaw
SENSORS = {"lidar_front": ((0.99, 0.0, 0.26), 0.0), "lidar_back": ((-0.95, 0.0, 0.26), math.pi)}
FRAMES = {"lidar_front": "base_scan_front", "lidar_back": "base_scan_back"}

# the fixture world's boxes as (min corner, max corner); the ground plane is z = 0
BOXES = {
    "front_wall": ((3.99, -2.0, 0.0), (4.19, 3.0, 1.0)),
    "back_box": ((-3.15, -0.2, 0.0), (-2.95, 0.8, 1.0)),
    "side_post": ((-0.2, 6.0, 0.0), (0.2, 6.4, 1.0)),
}
FRONT_WALL_DISTANCE = 3.00  # from the front lidar at x 0.99 to the wall's face at x 3.99
BACK_BOX_DISTANCE = 2.00  # from the back lidar at x −0.95 to the box's face at x −2.95

ANGLES = np.linspace(-ANGLE_MAX, ANGLE_MAX, SAMPLES)
CENTRE = [SAMPLES // 2 - 1, SAMPLES // 2]  # the two rays either side of 0 (±0.0019 rad)

Floats = npt.NDArray[np.float64]


# --- the geometric model ---------------------------------------------------------------------


def sensor_pose(robot: tuple[Sequence[float], Sequence[float]], sensor: str) -> tuple[Floats, Floats]:
    """(position, rotation matrix) of a lidar in the world, from the robot's model pose."""
    (xyz, quat), (offset, yaw) = robot, SENSORS[sensor]
    rot = quaternion_to_matrix(tuple(quat))
    local = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(xyz) + rot @ np.asarray(offset), rot @ local


def true_ranges(
    origin: Floats, rot: Floats, boxes: Mapping[str, tuple[Sequence[float], Sequence[float]]], grow: float = 0.0
) -> Floats:
    """Distance along each ray to the nearest box (grown by `grow` on every side) or the floor; inf past range_max."""
    directions = np.stack([np.cos(ANGLES), np.sin(ANGLES), np.zeros_like(ANGLES)], axis=1) @ rot.T
    best = np.full(SAMPLES, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for low, high in boxes.values():
            lo, hi = np.asarray(low) - grow, np.asarray(high) + grow
            t1, t2 = (lo - origin) / directions, (hi - origin) / directions
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (far >= near) & (near > 0)
            best = np.where(hit & (near < best), near, best)
        floor = -origin[2] / directions[:, 2]
        best = np.where((floor > 0) & (floor < best), floor, best)
    return np.where((best >= RANGE_MIN) & (best <= RANGE_MAX), best, np.inf)


def expected(robot: tuple[Sequence[float], Sequence[float]], sensor: str) -> tuple[Floats, npt.NDArray[np.bool_]]:
    """The true ranges, and which rays are unambiguous (same verdict with the boxes 1 cm bigger or smaller)."""
    origin, rot = sensor_pose(robot, sensor)
    nominal = true_ranges(origin, rot, BOXES)
    grown, shrunk = true_ranges(origin, rot, BOXES, 0.01), true_ranges(origin, rot, BOXES, -0.01)
    clear = np.isfinite(grown) == np.isfinite(shrunk)
    with np.errstate(invalid="ignore"):
        clear &= ~np.isfinite(nominal) | (np.abs(grown - shrunk) < 0.05)  # not where a ray changes face at a corner
    return nominal, clear


def ranges_of(scan: Any) -> Floats:
    return np.asarray(scan.ranges, dtype=float)


def compare(scan: Any, robot: tuple[Sequence[float], Sequence[float]], sensor: str) -> list[str]:
    """What disagrees between a scan and the model: ray by ray, finite vs inf and the range."""
    measured = ranges_of(scan)
    truth, clear = expected(robot, sensor)
    problems = []
    for i in np.flatnonzero(clear):
        m, t = measured[i], truth[i]
        if np.isfinite(t) != np.isfinite(m) or (np.isfinite(t) and abs(m - t) > TOLERANCE):
            problems.append(f"{sensor} ray {i} ({math.degrees(ANGLES[i]):+.2f}°) reads {m:.4f}, geometry says {t:.4f}")
    return problems


# --- the server ------------------------------------------------------------------------------


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Any:
    with running_server(str(WORLD), extra=(*AT_ORIGIN, *CHEAP_CAMERAS)) as server:
        yield server


fresh_world = reset_before_each(SETTLE_STEPS)


def _now_ns(sim: SimServer) -> int:
    return round(sim.state()["sim_time"] * 1e9)


def _scans(sim: SimServer) -> tuple[Collector[Any], Collector[Any], Collector[Any]]:
    front, back = sim.subscribe("lidar_front", LASER_SCAN), sim.subscribe("lidar_back", LASER_SCAN)
    truth = sim.subscribe("model/flexley_tug/pose", POSE_STAMPED)
    sim.prime(front, back, truth)
    return front, back, truth


def _step_to_scan(sim: SimServer) -> int:
    """Steps to the next multiple of the scan period; returns that sim time."""
    now = _now_ns(sim)
    target = (now // SCAN_NS + 1) * SCAN_NS
    sim.step((target - now) // STEP_NS)
    assert _now_ns(sim) == target
    return target


def _robot_at(truth: Collector[Any], ns: int) -> tuple[Sequence[float], Sequence[float]]:
    return pose_of(truth.wait_stamp(ns, what="ground-truth pose").pose)


# --- tests -----------------------------------------------------------------------------------


def test_message_fields_and_stamps(sim: SimServer) -> None:
    """Frames, angles, limits, scan_time 0.2 s; stamped with the sim time of the scan (multiples of 0.2 s)."""
    front, back, _ = _scans(sim)
    t = _step_to_scan(sim)
    for name, collector in (("lidar_front", front), ("lidar_back", back)):
        scan = collector.wait_stamp(t, what=name)
        assert scan.header.frame_id == FRAMES[name]
        assert (scan.angle_min, scan.angle_max) == (
            pytest.approx(-ANGLE_MAX, abs=1e-6),
            pytest.approx(ANGLE_MAX, abs=1e-6),
        )
        assert scan.angle_increment == pytest.approx(2 * ANGLE_MAX / (SAMPLES - 1), rel=1e-6)
        assert (scan.range_min, scan.range_max) == (pytest.approx(RANGE_MIN), pytest.approx(RANGE_MAX))
        assert scan.scan_time == pytest.approx(0.2) and scan.time_increment == 0.0
        assert len(scan.ranges) == SAMPLES
        stamps = [stamp_ns(m) for m in collector.messages()]
        assert all(s % SCAN_NS == 0 for s in stamps[1:]), f"{name} stamps off the 0.2 s grid: {stamps}"


def test_straight_and_oblique_rays_read_the_geometry(sim: SimServer) -> None:
    """Centre rays: the wall 3.00 m ahead, the box 2.00 m behind; every other ray: d / cos θ, or inf past the edges."""
    front, back, truth = _scans(sim)
    t = _step_to_scan(sim)
    robot = _robot_at(truth, t)
    assert math.hypot(robot[0][0], robot[0][1]) < 0.002, f"the robot settled at {robot[0]}, not at the origin"
    f, b = ranges_of(front.wait_stamp(t)), ranges_of(back.wait_stamp(t))

    # straight ahead: the centre rays are ±0.0019 rad off the axis, 3.00 / cos(0.0019) = 3.0000057
    assert f[CENTRE] == pytest.approx([FRONT_WALL_DISTANCE] * 2, abs=RESOLUTION), f"front centre rays {f[CENTRE]}"
    assert b[CENTRE] == pytest.approx([BACK_BOX_DISTANCE] * 2, abs=RESOLUTION), f"back centre rays {b[CENTRE]}"

    # oblique rays on the wall: the wall's face is a plane x = 3.99, so range = 3.00 / cos θ
    on_wall = np.abs(ANGLES) < math.atan(2.0 / 3.0) - 0.01  # the wall ends at y −2.0 (−33.7°) and +3.0 (+45°)
    assert np.isfinite(f[on_wall]).all()
    error = np.abs(f[on_wall] - FRONT_WALL_DISTANCE / np.cos(ANGLES[on_wall]))
    assert error.max() <= TOLERANCE, (
        f"worst oblique ray off by {error.max():.4f} m at {math.degrees(ANGLES[on_wall][error.argmax()]):.1f}°"
    )
    assert f[on_wall].max() > 3.5, "the oblique rays cover the wall out to ~3.6 m"

    # which rays hit: the wall spans −33.7°..+45.0° (asymmetric, so a mirrored scan would fail); beyond, nothing
    hits = np.degrees(ANGLES[np.isfinite(f)])
    assert hits.min() == pytest.approx(-math.degrees(math.atan(2 / 3)), abs=0.25), "ray spacing is 0.22°"
    assert hits.max() == pytest.approx(45.0, abs=0.25)
    assert np.isinf(f[np.abs(ANGLES) > math.radians(46)]).all(), "nothing within 10 m beyond the wall's edges"
    # back lidar looks −x, its +θ towards −y: the box (y −0.2..0.8, 2 m away) spans −21.8°..+5.7° of its scan
    back_hits = np.degrees(ANGLES[np.isfinite(b)])
    assert back_hits.min() == pytest.approx(-math.degrees(math.atan(0.8 / 2)), abs=0.25)
    assert back_hits.max() == pytest.approx(math.degrees(math.atan(0.2 / 2)), abs=0.25)

    # and every ray of both, against the model
    problems = compare(front.wait_stamp(t), robot, "lidar_front") + compare(back.wait_stamp(t), robot, "lidar_back")
    assert not problems, "\n".join(problems[:20])
    print(
        f"\nmeasured: front centre {f[CENTRE]}, back centre {b[CENTRE]}, oblique worst error {error.max():.4f} m "
        f"over {on_wall.sum()} rays up to {f[on_wall].max():.2f} m; front hits {hits.min():.2f}°..{hits.max():.2f}°, "
        f"back hits {back_hits.min():.2f}°..{back_hits.max():.2f}°"
    )


def test_front_sees_ahead_back_sees_behind(sim: SimServer) -> None:
    """Each lidar's rays that point at a box read that box; none reads the other lidar's box.

    Were a lidar turned the wrong way, the front one would read the back box at 3.94 m
    (0.99 + 0.95 + 2.00) through the invisible robot, and the back one the wall at 4.94 m.
    """
    front, back, _ = _scans(sim)
    t = _step_to_scan(sim)
    f, b = ranges_of(front.wait_stamp(t)), ranges_of(back.wait_stamp(t))
    ahead = np.abs(ANGLES) < math.radians(5)
    assert np.allclose(f[ahead], FRONT_WALL_DISTANCE / np.cos(ANGLES[ahead]), atol=TOLERANCE)
    assert np.allclose(b[ahead], BACK_BOX_DISTANCE / np.cos(ANGLES[ahead]), atol=TOLERANCE)
    # and the back lidar sees nothing of the wall: its only returns are the box's, 2.00..2.15 m
    assert b[np.isfinite(b)].max() < 2.2, f"the back lidar reads up to {b[np.isfinite(b)].max():.2f} m"


def test_nothing_in_range_reads_inf(sim: SimServer) -> None:
    """Rays that reach no box within 10 m read +inf (REP-117), not range_max; the side post at 90° is out of view."""
    front, back, _ = _scans(sim)
    t = _step_to_scan(sim)
    f, b = ranges_of(front.wait_stamp(t)), ranges_of(back.wait_stamp(t))
    side = np.abs(ANGLES) > math.radians(50)
    assert np.isposinf(f[side]).all() and np.isposinf(b[side]).all()
    finite = np.concatenate([f[np.isfinite(f)], b[np.isfinite(b)]])
    assert finite.max() < 5.0, "no finite reading from anything but the wall and the box"
    assert not np.any(np.isneginf(f)) and not np.any(np.isnan(f)) and not np.any(np.isnan(b))
    print(f"\nmeasured: {np.isinf(f).sum()} of front's and {np.isinf(b).sum()} of back's {SAMPLES} rays read inf")


def test_a_near_box_reads_short(sim: SimServer) -> None:
    """The check that nothing reads short is not vacuous: the wall 0.30 m from the front lidar reads 0.30."""
    front, _, truth = _scans(sim)
    (_, _, z), _ = sim.pose()
    # the front lidar at x + 0.99; the wall's face at 3.99
    reply = sim.call("set_pose", {"name": "flexley_tug", "position": {"x": 3.99 - 0.30 - 0.99, "y": 0.0, "z": z}})
    assert reply.get("ok") is True, reply
    sim.step(200)
    t = _step_to_scan(sim)
    robot = _robot_at(truth, t)
    f = ranges_of(front.wait_stamp(t))
    assert f[CENTRE] == pytest.approx([0.30, 0.30], abs=RESOLUTION), (
        f"front centre rays {f[CENTRE]} at 0.30 m from the wall"
    )
    assert np.nanmin(f) < 0.5
    problems = compare(front.wait_stamp(t), robot, "lidar_front")
    assert not problems, "\n".join(problems[:20])


def test_own_robot_never_seen_while_driving(sim: SimServer) -> None:
    """Driving an arc (0.5 m/s, 0.5 rad/s) for 4 s: no range below 0.5 m in any scan, every scan matches the geometry."""
    front, back, truth = _scans(sim)
    t0 = _step_to_scan(sim)
    sim.drive(0.5, 0.5)
    sim.step(4000)
    t1 = t0 + 4_000_000_000
    sim.drive(0.0, 0.0)
    sim.step(1)
    front.wait_stamp(t1, what="the last front scan")
    back.wait_stamp(t1, what="the last back scan")
    scans = {
        name: [m for m in c.messages() if t0 < stamp_ns(m) <= t1]
        for name, c in (("lidar_front", front), ("lidar_back", back))
    }
    assert [len(s) for s in scans.values()] == [20, 20], "5 Hz for 4 s"
    shortest, problems = math.inf, []
    for name, messages in scans.items():
        for scan in messages:
            r = ranges_of(scan)
            shortest = min(shortest, float(np.min(r)))
            assert not np.any(r < 0.5), (
                f"{name} at {stamp_ns(scan) / 1e9:.1f} s reads {np.min(r):.3f} m: the robot itself?"
            )
            problems += compare(scan, _robot_at(truth, stamp_ns(scan)), name)
    (x, y, _), _ = sim.pose()
    assert math.hypot(x, y) > 1.0, "the robot moved"
    assert not problems, "\n".join(problems[:20])
    print(f"\nmeasured while driving: shortest range {shortest:.2f} m over 40 scans, all rays agree with the geometry")


def test_rates_over_ten_seconds(sim: SimServer) -> None:
    """Lockstep, 10 s of sim time: 50 scans from each lidar, 2000 IMU samples (±1); world state reports 5 and 200 Hz."""
    front, back, _ = _scans(sim)
    imu = sim.subscribe("imu_scan", IMU)
    sim.prime(imu)
    t0 = _step_to_scan(sim)
    for _ in range(10):
        sim.step(1000)
    t1 = t0 + 10_000_000_000
    for collector, period in ((front, SCAN_NS), (back, SCAN_NS), (imu, 5_000_000)):
        collector.wait_stamp(t1 - t1 % period, what="the last message")
    counts = {
        name: sum(1 for m in c.messages() if t0 < stamp_ns(m) <= t1)
        for name, c in (("lidar_front", front), ("lidar_back", back), ("imu_scan", imu))
    }
    assert counts["lidar_front"] == pytest.approx(50, abs=1) and counts["lidar_back"] == pytest.approx(50, abs=1), (
        counts
    )
    assert counts["imu_scan"] == pytest.approx(2000, abs=1), counts
    sensors = {scoped.rsplit("/", 1)[-1]: v for scoped, v in sim.state()["sensors"].items()}  # by sensor name
    assert sensors["lidar_front"]["rate_hz"] == pytest.approx(5.0, abs=1.0)
    assert sensors["lidar_back"]["rate_hz"] == pytest.approx(5.0, abs=1.0)
    assert sensors["imu_sensor"]["rate_hz"] == pytest.approx(200.0, abs=1.0)
    print(
        f"\nmeasured over 10 s: {counts}; world state { ({k: v['rate_hz'] for k, v in sensors.items() if 'camera' not in k}) }"
    )


# --- the robot's own body, made to lie across the rays ---------------------------------------


def _robot_with_lidars_across_the_body(tmp: Path) -> Path:
    """simbot's robot with both lidars moved to 0.3 m ahead of the chassis, looking back across it (−x).

    Front lidar (link at (1.0, 0, 0.04) yaw π) → at (1.3, 0, −0.05) in base_footprint: 0.045 m above
    the floor, level with the castors and the wheels; back lidar (link at (−0.9, 0, 0.04) yaw 0) →
    at (1.3, 0, 0.12): through the chassis box (z −0.025..0.205).
    """
    text = ROBOT_SDF.read_text()
    front_pose = "<pose>0.01 0 0.22 0 0 3.141592653589793</pose>"
    back_pose = "<pose>-0.05 0 0.22 0 0 3.141592653589793</pose>"
    for old, new in (
        (front_pose, "<pose>-0.3 0 -0.09 0 0 0</pose>"),
        (back_pose, "<pose>2.2 0 0.08 0 0 3.141592653589793</pose>"),
    ):
        assert text.count(old) == 1, f"the robot SDF no longer has {old}"
        text = text.replace(old, new)
    text = text.replace("../meshes/", f"{REPO / 'meshes'}/")
    path = tmp / "robot_lidars_across.sdf"
    path.write_text(text)
    return path


def test_rays_through_the_robot_hit_it_unless_blinded() -> None:
    """Physics alone: rays from 0.3 m ahead of the tug back across it hit the chassis, castors and wheels; blinded, they pass."""
    world = load_world(WORLD)
    physics = Physics(world)
    try:
        for model in world.models:
            physics.add_model(model)
        physics.add_model(load_model(ROBOT_SDF), "flexley_tug", Pose((0.0, 0.0, 0.1)))
        for _ in range(SETTLE_STEPS):
            physics.step()
        (_, _, z), _ = physics.model_pose("flexley_tug")
        # base_footprint z 0.0955; rays towards −x at 0.12 (chassis), −0.05 at y 0.17 (a castor) and y 0.2 (a wheel)
        starts = np.array([[1.3, 0.0, z + 0.12], [1.3, 0.17, z - 0.05], [0.8, 0.2, z - 0.05]])
        ends = starts - np.array([10.0, 0.0, 0.0])
        seen = physics.cast_rays(starts, ends) * 10.0
        assert seen == pytest.approx(
            [0.25, 0.38 - 0.025, 0.22 - 0.075 * math.sqrt(1 - (0.03 / 0.075) ** 2)], abs=0.01
        ), seen
        blind = physics.cast_rays(starts, ends, blind_to="flexley_tug") * 10.0
        assert blind[0] == pytest.approx(1.3 + 2.95, abs=0.01), f"through the chassis to the back box: {blind}"
        assert np.all(np.isnan(blind[1:]) | (blind[1:] > 2.3)), f"castor and wheel still seen: {blind}"
    finally:
        physics.close()


def test_lidars_looking_across_the_robot_do_not_see_it(tmp_path: Path) -> None:
    """End to end: lidars moved to look back across the tug's chassis, wheels and castors read past them."""
    robot = _robot_with_lidars_across_the_body(tmp_path)
    with running_server(str(WORLD), extra=("--robot", str(robot), *AT_ORIGIN, *CHEAP_CAMERAS)) as sim:
        front, back = sim.subscribe("lidar_front", LASER_SCAN), sim.subscribe("lidar_back", LASER_SCAN)
        sim.prime(front, back)
        sim.step(SETTLE_STEPS)
        t = _step_to_scan(sim)
        low, high = ranges_of(front.wait_stamp(t)), ranges_of(back.wait_stamp(t))
    # the robot ends 2.35 m behind the lidars (chassis back at x −1.05): anything nearer would be the robot
    for name, r in (("low (castors, wheels)", low), ("high (chassis)", high)):
        finite = r[np.isfinite(r)]
        assert finite.size and finite.min() > 2.35, f"{name} lidar reads {finite.min() if finite.size else None} m"
    assert high[CENTRE] == pytest.approx([1.3 + 2.95] * 2, abs=RESOLUTION), (
        f"through the chassis to the back box: {high[CENTRE]}"
    )
    print(
        f"\nmeasured across the robot: nearest return {min(low[np.isfinite(low)].min(), high[np.isfinite(high)].min()):.2f} m, centre {high[CENTRE]}"
    )


# --- the reference robot ---------------------------------------------------------------------


def test_reference_robot_sensors_description(reference: Path) -> None:
    """The original Gazebo SDF: two 720-ray lidars, six cameras, an IMU, with their own topics, rates and noise."""
    robot = load_model(reference / "urdf" / "Flexley_Tug.sdf")
    sensors = {s.name: (link.name, s) for link, s in robot.sensors()}
    assert sorted(s.type for _, s in sensors.values()) == ["camera"] * 6 + ["gpu_lidar"] * 2 + ["imu"]
    for name, link in (("lidar_front", "base_scan_front"), ("lidar_back", "base_scan_back")):
        on, lidar = sensors[name]
        assert on == link and lidar.topic == name and lidar.frame_name == link and lidar.update_rate == 5
        spec = LidarParams.from_sdf(lidar)
        assert spec.horizontal.samples == SAMPLES
        assert (spec.horizontal.min_angle, spec.horizontal.max_angle) == (-ANGLE_MAX, ANGLE_MAX)
        assert (spec.range_min, spec.range_max, spec.range_resolution) == (RANGE_MIN, RANGE_MAX, RESOLUTION)
    on, imu = sensors["imu_sensor"]
    assert on == "imu_link" and imu.topic == "/imu_scan" and imu.frame_name == "imu_link" and imu.update_rate == 200
    imu_params = ImuParams.from_sdf(imu)
    assert [n.stddev for n in imu_params.angular_velocity_noise] == [2e-4] * 3
    assert [n.stddev for n in imu_params.linear_acceleration_noise] == [1.7e-2] * 3
    cameras = [s for _, s in sensors.values() if s.type == "camera"]
    assert sorted(c.topic or "" for c in cameras) == sorted(
        f"{n}_cam" for n in ("front", "back", "front_right", "back_right", "front_left", "back_left")
    )
    assert all(c.update_rate == 30 for c in cameras)


def test_reference_robot_publishes_lidars_and_imu(reference: Path) -> None:
    """`--robot` the reference SDF: lidar_front, lidar_back, imu_scan at 5/5/200 Hz, the lidars reading the boxes."""
    robot = reference / "urdf" / "Flexley_Tug.sdf"
    with running_server(str(WORLD), extra=("--robot", str(robot), *AT_ORIGIN, *CHEAP_CAMERAS)) as sim:
        front, back, imu = (
            sim.subscribe("lidar_front", LASER_SCAN),
            sim.subscribe("lidar_back", LASER_SCAN),
            sim.subscribe("imu_scan", IMU),
        )
        sim.prime(front, back, imu)
        t0 = _step_to_scan(sim)
        sim.step(2000)
        t1 = t0 + 2_000_000_000
        last = {
            name: c.wait_stamp(t1, what=name)
            for name, c in (("lidar_front", front), ("lidar_back", back), ("imu_scan", imu))
        }
        counts = {
            name: sum(1 for m in c.messages() if t0 < stamp_ns(m) <= t1)
            for name, c in (("lidar_front", front), ("lidar_back", back), ("imu_scan", imu))
        }
        sensors = {scoped.rsplit("/", 1)[-1]: v for scoped, v in sim.state()["sensors"].items()}  # by sensor name
    assert counts == {
        "lidar_front": pytest.approx(10, abs=1),
        "lidar_back": pytest.approx(10, abs=1),
        "imu_scan": pytest.approx(400, abs=1),
    }, counts
    assert {k: sensors[k]["rate_hz"] for k in ("lidar_front", "lidar_back", "imu_sensor")} == {
        "lidar_front": pytest.approx(5, abs=1),
        "lidar_back": pytest.approx(5, abs=1),
        "imu_sensor": pytest.approx(200, abs=1),
    }
    assert [last[k].header.frame_id for k in last] == ["base_scan_front", "base_scan_back", "imu_link"]
    # its yaws are 3.14, not π: the front lidar looks 0.0032 rad right of +x, still 3.00 m to the wall
    assert ranges_of(last["lidar_front"])[CENTRE] == pytest.approx([FRONT_WALL_DISTANCE] * 2, abs=RESOLUTION)
    assert ranges_of(last["lidar_back"])[CENTRE] == pytest.approx([BACK_BOX_DISTANCE] * 2, abs=RESOLUTION)
    assert last["imu_scan"].linear_acceleration.z == pytest.approx(9.8, abs=0.1), "at rest: +g, within 5 σ of its noise"
