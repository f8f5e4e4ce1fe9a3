"""`simbot monitor` against a real warehouse server in real time: its rows hold what the bus carries.

One server for the module (cameras 160 × 120 at 5 Hz), with the lidar merger and the camera
stitcher. The robot stands at its spawn pose, so what the monitor shows
can be checked against physics and against the test's own subscriptions:
- the IMU reads the specific force +g on z, within 5σ of its noise (σ 1.7e-2 m/s²) and the
  table's rounding (0.005);
- a lidar's scans repeat (no noise in the SDF, the robot at rest): the nearest return shown is
  the minimum of the test's own scan within the range resolution (0.01) and the rounding, at the
  bearing of one of the rays that reach within 0.01 of that minimum;
- rates are per wall second over the last 3 s: compared with the clock's (100 per sim second)
  in the same table, they are free of the machine's real-time factor; a delivery late by up to
  δ = 0.1 s at either end of the span moves a rate by 2δ / span (span = 3 s less one period).
"""

from __future__ import annotations

import math
import re
import signal
import subprocess
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from client_helpers import bus_args, client_command, client_process, pty_client
from conftest import CAMERAS
from server_helpers import REPO, SimServer, running_server, wait_until

from simbot.clients.terminal import ENTER_ALTERNATE, HIDE_CURSOR, HOME_AND_CLEAR, LEAVE_ALTERNATE, SHOW_CURSOR

WORLD_EXTRA = ("--camera-size", "160x120", "--camera-rate", "5")
LASER_SCAN, CAMERA_INFO = "sensor_msgs/msg/LaserScan", "sensor_msgs/msg/CameraInfo"
TIMEOUT_S = 60.0
HORIZON_S, JITTER_S, CLOCK_HZ, LIDAR_HZ = 3.0, 0.1, 100.0, 5.0
G, ACCEL_SIGMA, ROUNDING = 9.8, 1.7e-2, 0.005
RESOLUTION = 0.01
POSE_TOLERANCE = 0.01 + ROUNDING
SPAWN, TROLLEY = (-2.5, 0.0), (1.0, 0.2)
BLOCKS = 5
"""Tables to wait for: the rates' 3 s horizon is full from the fourth on."""
NO_MESSAGE = "no message yet"
"""The monitor's latest cell of a key that has had none."""


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Iterator[SimServer]:
    """The warehouse in real time, with the merger and the stitcher."""
    with (
        running_server("warehouse", mode="realtime", extra=WORLD_EXTRA) as server,
        client_process(server, "merger"),
        client_process(server, "stitcher"),
    ):
        yield server


def parse_block(block: str) -> tuple[str, dict[str, tuple[str, str]]]:
    """One printed table: (its heading, {key: (rate, latest)})."""
    lines = block.splitlines()
    assert re.split(r"\s{2,}", lines[1].strip()) == ["KEY", "RATE", "LATEST"], block
    rows = {}
    for line in lines[2:]:
        key, rate, latest = re.split(r"\s{2,}", line.strip(), maxsplit=2)
        rows[key] = (rate, latest)
    return lines[0], rows


@pytest.fixture(scope="module", name="table")
def table_fixture(sim: SimServer) -> tuple[str, dict[str, tuple[str, str]], dict[str, Any]]:
    """The monitor's first table (from a pipe: plain blocks) from the fifth on that shows the
    stitcher's panorama (a loaded machine starts the stitcher later), and the test's own scans and
    camera_info taken meanwhile."""
    keys = ["lidar_front", "lidar_back", "scan"]
    scans = {key: sim.subscribe(key, LASER_SCAN) for key in keys}
    info = sim.subscribe("camera_360/camera_info", CAMERA_INFO)
    with client_process(sim, "monitor") as monitor:
        what = f"a table from the {BLOCKS}th on with the panorama"
        wait_until(lambda: complete_table(monitor.stdout()), timeout=TIMEOUT_S, what=what)
        assert monitor.alive(), monitor.stderr()
        found = complete_table(monitor.stdout())
    assert found is not None
    own: dict[str, Any] = {
        key: collector.wait_count(1, timeout=TIMEOUT_S, what=f"{key} scans")[-1] for key, collector in scans.items()
    }
    own["camera_360/camera_info"] = info.wait_count(1, timeout=TIMEOUT_S, what="panorama camera_info")[-1]
    sim.unsubscribe_all()
    heading, rows = found
    return heading, rows, own


def complete_table(text: str) -> tuple[str, dict[str, tuple[str, str]]] | None:
    """The last whole table printed, from the BLOCKS-th on, once its panorama row has a message."""
    blocks = text.split("\n\n")[:-1]
    if len(blocks) < BLOCKS:
        return None
    heading, rows = parse_block(blocks[-1])
    return (heading, rows) if rows.get("camera_360/camera_info", ("", NO_MESSAGE))[1] != NO_MESSAGE else None


def numbers(text: str) -> list[float]:
    return [float(n) for n in re.findall(r"[-+]?\d+(?:\.\d+)?", text)]


def hertz(cell: str) -> float:
    found = re.fullmatch(r"([0-9.]+) Hz", cell)
    assert found, f"not a rate: {cell!r}"
    return float(found[1])


def test_the_heading_names_the_world_its_sim_time_and_real_time_factor(
    table: tuple[str, Any, Any], sim: SimServer
) -> None:
    heading = table[0]
    found = re.fullmatch(r"world (\S+)  sim time ([0-9.]+) s  real-time factor ([0-9.]+)  \(realtime\)", heading)
    assert found, heading
    assert found[1] == sim.world and float(found[2]) > 0 and float(found[3]) > 0


def test_the_imu_reads_gravity_up_and_no_turn(table: tuple[str, Any, Any]) -> None:
    latest = table[1]["imu_scan"][1]
    found = re.fullmatch(r"accel (\S+) (\S+) (\S+) m/s²; gyro (\S+) (\S+) (\S+) rad/s", latest)
    assert found, latest
    accel, gyro = [float(v) for v in found.groups()[:3]], [float(v) for v in found.groups()[3:]]
    assert accel[2] == pytest.approx(G, abs=5 * ACCEL_SIGMA + ROUNDING)
    assert all(abs(a) <= 5 * ACCEL_SIGMA + ROUNDING for a in accel[:2])
    assert all(abs(w) <= 0.001 + 0.0005 for w in gyro)  # σ 2e-4 rad/s, shown to 0.001


@pytest.mark.parametrize(
    ("key", "nominal"),
    [("lidar_front", LIDAR_HZ), ("lidar_back", LIDAR_HZ), ("odom", 50.0), ("imu_scan", 200.0), ("joint_states", 30.0)],
)
def test_rates_match_the_nominal_ones_against_the_clock(table: tuple[str, Any, Any], key: str, nominal: float) -> None:
    check_rate(table[1], key, "clock", nominal)


def check_rate(rows: dict[str, tuple[str, str]], key: str, clock: str, nominal: float) -> None:
    """The row's rate against the clock's is nominal per sim second against 100: the span of each
    rate (the horizon less one interval between arrivals, in wall seconds) moved by up to 2δ."""
    key_hz, clock_hz = hertz(rows[key][0]), hertz(rows[clock][0])
    tolerance = 2 * JITTER_S / (HORIZON_S - 1 / key_hz) + 2 * JITTER_S / (HORIZON_S - 1 / clock_hz)
    ratio = key_hz / clock_hz
    assert ratio == pytest.approx(nominal / CLOCK_HZ, rel=tolerance), f"{key} {rows[key][0]}, clock {rows[clock][0]}"


def nearest_candidates(scan: Any) -> tuple[float, list[float]]:
    """The scan's nearest valid range, and the bearings (degrees) of every ray within one resolution of it."""
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    bearings = np.degrees(scan.angle_min + np.arange(ranges.size) * scan.angle_increment)
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    nearest = float(ranges[valid].min())
    return nearest, list(bearings[valid & (ranges <= nearest + RESOLUTION)])


@pytest.mark.parametrize("key", ["lidar_front", "lidar_back", "scan"])
def test_the_nearest_return_is_the_scans_minimum(table: tuple[str, Any, Any], key: str) -> None:
    latest = table[1][key][1]
    found = re.fullmatch(r"nearest ([0-9.]+) m at ([-+]\d+)°; (\d+)/(\d+) returns \((\S+)\)", latest)
    assert found, latest
    nearest, bearings = nearest_candidates(table[2][key])
    assert float(found[1]) == pytest.approx(nearest, abs=RESOLUTION + ROUNDING)
    assert min(abs(float(found[2]) - b) for b in bearings) <= 0.5  # shown to the degree
    assert found[5] == table[2][key].header.frame_id


def test_odometry_and_ground_truth_poses_are_where_the_robot_and_trolley_stand(table: tuple[str, Any, Any]) -> None:
    rows = table[1]
    x, y, yaw = numbers(rows["odom"][1])[:3]
    assert math.hypot(x, y) <= POSE_TOLERANCE and abs(yaw) <= 0.1  # at rest where odometry began
    for key, (ex, ey) in (("model/flexley_tug/pose", SPAWN), ("model/trolley/pose", TROLLEY)):
        x, y = numbers(rows[key][1])[:2]
        assert math.hypot(x - ex, y - ey) <= POSE_TOLERANCE, rows[key]


def test_the_docking_state_and_the_camera_sizes_are_shown(table: tuple[str, Any, Any]) -> None:
    rows = table[1]
    assert rows["detachable_joint/state"][1] == "detached"
    for camera in CAMERAS:  # the world state's sensors, by scoped name
        row = rows[f"flexley_tug/base_link/{camera}"]
        assert row[1].startswith("160x120; "), row


def test_the_panorama_size_is_its_camera_infos(table: tuple[str, Any, Any]) -> None:
    info = table[2]["camera_360/camera_info"]
    assert table[1]["camera_360/camera_info"][1] == f"{info.width}x{info.height}"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_on_a_terminal_it_is_a_full_screen_redrawn_in_place_and_a_signal_gives_the_terminal_back(
    sim: SimServer, sig: signal.Signals
) -> None:
    """The alternate screen, redrawn whole each period; Ctrl-C (SIGINT) or SIGTERM leaves it (the user's
    screen comes back), shows the cursor, leaves the terminal's attributes as they were, and exits 0."""
    with pty_client(client_command("monitor", *bus_args(sim), "--period", "0.5")) as screen:
        wait_until(lambda: screen.raw_output().count(HOME_AND_CLEAR) >= 3, timeout=TIMEOUT_S, what="three redraws")
        assert screen.raw_output().startswith(ENTER_ALTERNATE + HIDE_CURSOR)
        screen.wait_for(r"imu_scan\s+[0-9.]+ Hz  accel")
        screen.process.send_signal(sig)
        assert screen.wait_exit() == 0
        assert screen.raw_output().rstrip("\r\n").endswith(SHOW_CURSOR + LEAVE_ALTERNATE)
        assert screen.attributes() == screen.initial


def test_a_period_of_zero_is_one_line_and_exit_2(sim: SimServer) -> None:
    result = subprocess.run(
        client_command("monitor", *bus_args(sim), "--period", "0"),
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=TIMEOUT_S,
    )
    last = result.stderr.strip().splitlines()[-1]  # argparse's usage, then the one line that says what is wrong
    assert (
        result.returncode == 2
        and last.startswith("simbot monitor: error: argument --period")
        and "Traceback" not in result.stderr
    ), result.stderr
