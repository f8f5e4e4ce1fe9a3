"""`simbot topics` and `simbot echo` against a real warehouse server in real time: every key of SPEC §4.

One server for the module (cameras 160 × 120 at 5 Hz: listed and decoded, cheap to render),
with the lidar merger and the camera stitcher, whose keys SPEC §4 lists too. Client programs run
as real processes on the server's bus.

Rates. The server runs in real time, but a loaded machine may hold it below a real-time factor
of 1, and every key's rate per wall second scales with it alike; so each key's measured rate is
compared with `clock`'s (100 per sim second) measured in the same window: rate / clock rate =
nominal / 100. `topics` rates a key as (n − 1) / (last arrival − first arrival); a delivery
delayed by up to δ at either end of the span moves the estimate by at most 2δ / span, where the
span is the window less one period. With δ = 0.1 s (a busy 2-core machine) and a 4 s window that
is 5.3 % for a 5 Hz lidar and 5 % for the clock: the ratio's tolerance is the sum of the two.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from client_helpers import bus_args, client_command, client_process
from conftest import CAMERAS
from server_helpers import REPO, SimServer, running_server, wait_until

from simbot.bus import encode, messages
from simbot.sim.systems.clock_publisher import CLOCK_RATE

WORLD_EXTRA = ("--camera-size", "160x120", "--camera-rate", "5")
WIDTH, HEIGHT = 160, 120
HFOV = 2.0944
WINDOW_S = 4.0
JITTER_S = 0.1
ECHO_WAIT_S = "30"
RUN_TIMEOUT_S = 60.0
G, ACCEL_SIGMA = 9.8, 1.7e-2
SPAWN = (-2.5, 0.0)
TROLLEY = (1.0, 0.2)
POSE_TOLERANCE = 0.01  # the robot settles on its tyres at rest; the trolley stands still
ANGLE_MAX = 1.396263
RANGE_MAX, FRONT_LIDAR_X = 10.0, 0.99

CLOCK, TWIST, ODOMETRY = "rosgraph_msgs/msg/Clock", "geometry_msgs/msg/Twist", "nav_msgs/msg/Odometry"
TF, STRING, EMPTY = "tf2_msgs/msg/TFMessage", "std_msgs/msg/String", "std_msgs/msg/Empty"
JOINT_STATE, IMU, LASER_SCAN = "sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu", "sensor_msgs/msg/LaserScan"
IMAGE, CAMERA_INFO, POSE_STAMPED = (
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/CameraInfo",
    "geometry_msgs/msg/PoseStamped",
)

# SPEC §4: key → (type, kind, the client that provides it; None for the server)
KEYS: dict[str, tuple[str, str]] = {
    "clock": (CLOCK, "pub"),
    "cmd_vel": (TWIST, "sub"),
    "odom": (ODOMETRY, "pub"),
    "tf": (TF, "pub"),
    "tf_static": (TF, "pub"),
    "robot_description": (STRING, "pub"),
    "joint_states": (JOINT_STATE, "pub"),
    "imu_scan": (IMU, "pub"),
    "lidar_front": (LASER_SCAN, "pub"),
    "lidar_back": (LASER_SCAN, "pub"),
    **{camera: (IMAGE, "pub") for camera in CAMERAS},
    **{f"{camera}/camera_info": (CAMERA_INFO, "pub") for camera in CAMERAS},
    "attach": (EMPTY, "sub"),
    "detach": (EMPTY, "sub"),
    "detachable_joint/state": (STRING, "pub"),
    "model/flexley_tug/pose": (POSE_STAMPED, "pub"),
    "model/trolley/pose": (POSE_STAMPED, "pub"),
    "lidar_front_fixed": (LASER_SCAN, "pub"),
    "lidar_back_fixed": (LASER_SCAN, "pub"),
    "scan": (LASER_SCAN, "pub"),
    "camera_360/image_raw": (IMAGE, "pub"),
    "camera_360/camera_info": (CAMERA_INFO, "pub"),
}
OUTPUTS = [key for key, (_, kind) in KEYS.items() if kind == "pub"]
NOMINAL_HZ = {
    "odom": 50.0,
    "tf": 90.0,  # odometry 50, the movable joints 30, the scene's moving models and world → odom 10
    "imu_scan": 200.0,
    "lidar_front": 5.0,
    "lidar_back": 5.0,
    "joint_states": 30.0,
    "model/trolley/pose": 50.0,
}
CLOCK_HZ = 100.0


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Iterator[SimServer]:
    """The warehouse in real time, with the merger and the stitcher."""
    with (
        running_server("warehouse", mode="realtime", extra=WORLD_EXTRA) as server,
        client_process(server, "merger"),
        client_process(server, "stitcher"),
    ):
        yield server


def run(sim: SimServer, name: str, *args: str) -> subprocess.CompletedProcess[str]:
    """`clients.<name> ARGS` on the server's bus, to its end."""
    return subprocess.run(
        client_command(name, *bus_args(sim), *args),
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=RUN_TIMEOUT_S,
    )


# --- topics ---------------------------------------------------------------------------------


def parse_table(text: str) -> dict[str, dict[str, str]]:
    """`topics`' table back as {key: {column: cell}} (cells never hold two spaces running)."""
    lines = text.strip().splitlines()
    header = re.split(r"\s{2,}", lines[0].strip())
    assert header == ["KEY", "TYPE", "WHO", "RATE", "BANDWIDTH"], lines[0]
    rows = {}
    for line in lines[1:]:
        cells = re.split(r"\s{2,}", line.strip())
        assert len(cells) == len(header), f"malformed row {line!r}"
        rows[cells[0]] = dict(zip(header, cells))
    return rows


def hertz(cell: str) -> float:
    found = re.fullmatch(r"([0-9.]+) Hz", cell)
    assert found, f"not a rate: {cell!r}"
    return float(found[1])


def bytes_per_second(cell: str) -> float:
    found = re.fullmatch(r"([0-9.]+) (B|kB|MB)/s", cell)
    assert found, f"not a bandwidth: {cell!r}"
    return float(found[1]) * {"B": 1.0, "kB": 1e3, "MB": 1e6}[found[2]]


@pytest.fixture(scope="module", name="table")
def table_fixture(sim: SimServer) -> dict[str, dict[str, str]]:
    """`simbot topics --window 4`, once the cameras render (so that their images come within the window:
    the render workers start only when someone first subscribes, which takes seconds)."""
    images = [sim.subscribe(camera, IMAGE) for camera in CAMERAS]
    for camera, images_of in zip(CAMERAS, images):
        images_of.wait_count(1, timeout=RUN_TIMEOUT_S, what=f"{camera} images")
    sim.unsubscribe_all()
    scans = sim.subscribe("scan", LASER_SCAN)
    scans.wait_count(1, timeout=RUN_TIMEOUT_S, what="merged scans")
    sim.unsubscribe_all()
    result = run(sim, "topics", "--window", str(WINDOW_S))
    assert result.returncode == 0, result.stderr
    return parse_table(result.stdout)


@pytest.mark.parametrize("key", list(KEYS))
def test_topics_lists_each_key_with_its_type_and_role(table: dict[str, dict[str, str]], key: str) -> None:
    typename, kind = KEYS[key]
    assert key in table, f"{key!r} missing from the table: {sorted(table)}"
    assert table[key]["TYPE"] == typename
    assert kind in table[key]["WHO"].split()


def test_topics_lists_world_control_as_services_and_latched_keys_as_latched(
    table: dict[str, dict[str, str]], sim: SimServer
) -> None:
    for service in ("control", "set_pose", "state"):
        row = table[f"world/{sim.world}/{service}"]
        assert (row["TYPE"], row["WHO"], row["RATE"]) == ("json", "srv", "-")
    for key in ("robot_description", "tf_static", "detachable_joint/state"):
        assert table[key]["RATE"] == "latched", table[key]


@pytest.mark.parametrize("key", list(NOMINAL_HZ))
def test_topics_measures_each_rate_against_the_clock(table: dict[str, dict[str, str]], key: str) -> None:
    clock_rate = hertz(table["clock"]["RATE"])
    nominal = NOMINAL_HZ[key]
    tolerance = 2 * JITTER_S / (WINDOW_S - 1 / nominal) + 2 * JITTER_S / (WINDOW_S - 1 / CLOCK_HZ)
    ratio = hertz(table[key]["RATE"]) / clock_rate
    assert ratio == pytest.approx(nominal / CLOCK_HZ, rel=tolerance), (
        f"{key}: {table[key]['RATE']} against clock {clock_rate} Hz"
    )


def test_topics_bandwidth_is_the_rate_times_the_message_size(table: dict[str, dict[str, str]]) -> None:
    """Bandwidth (n messages' bytes over the window W) / rate ((n − 1) / span) = one message's bytes × n/(n − 1) ×
    span/W; span/W is within 2δ + one period of 1 (≥ 0.9 for a 5 Hz lidar), n/(n − 1) ≤ 1.06 for ≥ 18 scans."""
    zeros = (0.0, 0.0, 0.0)
    scan = messages.laser_scan(
        0, "base_scan_front", (-ANGLE_MAX, ANGLE_MAX, 2 * ANGLE_MAX / 719), (0.0, 0.2), (0.08, 10.0), [math.inf] * 720
    )
    imu = messages.imu(0, "imu_link", (0.0, 0.0, 0.0, 1.0), zeros, zeros)
    for key, msg in (("lidar_front", scan), ("imu_scan", imu)):
        size = bytes_per_second(table[key]["BANDWIDTH"]) / hertz(table[key]["RATE"])
        assert size == pytest.approx(len(encode(msg)), rel=0.1), f"{key}: {table[key]}"


def test_topics_with_a_window_of_zero_lists_the_graph_without_rates(sim: SimServer) -> None:
    result = run(sim, "topics", "--window", "0")
    assert result.returncode == 0, result.stderr
    table = parse_table(result.stdout)
    assert table["odom"]["RATE"] == "-" and table["robot_description"]["RATE"] == "latched"


def test_topics_in_a_namespace_without_keys_is_one_line_and_exit_2(sim: SimServer) -> None:
    result = subprocess.run(
        client_command("topics", "--connect", sim.endpoint, "--namespace", "nobody_here", "--window", "0"),
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=RUN_TIMEOUT_S,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "nobody_here" in result.stderr, result.stderr


# --- echo: one decoded message of every output ----------------------------------------------


def _near(value: float, expected: float, tolerance: float) -> bool:
    return abs(value - expected) <= tolerance


def clock_ns(msg: dict[str, Any]) -> int:
    return int(msg["clock"]["sec"]) * 10**9 + int(msg["clock"]["nanosec"])


def check_clock(msg: dict[str, Any], key: str) -> None:
    """A tick of the 100 Hz clock (a multiple of 10 ms of sim time: the server steps 1 ms), past zero;
    where it lies in the server's time, `test_echo_reads_the_servers_sim_time_on_clock`."""
    assert clock_ns(msg) > 0 and clock_ns(msg) % round(1e9 / CLOCK_RATE) == 0, msg


def check_odometry(msg: dict[str, Any], key: str) -> None:
    assert (msg["header"]["frame_id"], msg["child_frame_id"]) == ("odom", "base_footprint")
    position = msg["pose"]["pose"]["position"]
    assert math.hypot(position["x"], position["y"]) < POSE_TOLERANCE  # at rest where odometry began
    assert msg["pose"]["covariance"]["length"] == 36  # summarised: 36 > 16


def check_tf(msg: dict[str, Any], key: str) -> None:
    pairs = {(t["header"]["frame_id"], t["child_frame_id"]): t["transform"]["translation"] for t in msg["transforms"]}
    if key == "tf":  # odom → base_footprint (50 Hz), the movable joints (30 Hz), or the scene's frames (10 Hz)
        assert {("odom", "base_footprint"), ("base_link", "front_left_wheel"), ("world", "odom")} & set(pairs)
    else:  # SPEC §1: base_link 0.09 m above base_footprint, the optical frames under the cameras
        assert pairs[("base_footprint", "base_link")]["z"] == pytest.approx(0.09)
        assert {("base_link", camera) for camera in CAMERAS} | {(c, f"{c}_optical_frame") for c in CAMERAS} <= set(
            pairs
        )


def check_string(msg: dict[str, Any], key: str) -> None:
    if key == "detachable_joint/state":
        assert msg["data"] == "detached"
    else:  # the head of the URDF; the whole of it is checked with --full below
        assert msg["data"].startswith("<?xml") and '<robot name="flexley_tug">' in msg["data"]


def check_joint_state(msg: dict[str, Any], key: str) -> None:
    assert len(msg["name"]) == 2 and all("front" in name for name in msg["name"]), msg["name"]
    assert len(msg["position"]) == len(msg["velocity"]) == 2


def check_imu(msg: dict[str, Any], key: str) -> None:
    assert msg["header"]["frame_id"] == "imu_link"
    assert _near(msg["linear_acceleration"]["z"], G, 5 * ACCEL_SIGMA)  # at rest: +g up, 5σ of noise


def check_scan(msg: dict[str, Any], key: str) -> None:
    ranges = msg["ranges"]
    if key in ("lidar_front", "lidar_back"):
        assert msg["header"]["frame_id"] == {"lidar_front": "base_scan_front", "lidar_back": "base_scan_back"}[key]
        assert (ranges["length"], ranges["dtype"], ranges["nan"]) == (720, "float32", 0)
        assert msg["angle_min"] == pytest.approx(-ANGLE_MAX) and msg["angle_max"] == pytest.approx(ANGLE_MAX)
    else:  # the merger's, in base_link; `scan` all round (SPEC §5)
        assert msg["header"]["frame_id"] == "base_link"
        if key == "scan":
            assert msg["angle_min"] == pytest.approx(-math.pi, abs=0.02) and msg["angle_max"] == pytest.approx(
                math.pi, abs=0.02
            )
    # in base_link a return lies up to the front lidar's offset (0.99 m, SPEC §1) beyond its 10 m
    reach = RANGE_MAX if key in ("lidar_front", "lidar_back") else RANGE_MAX + FRONT_LIDAR_X
    assert ranges["inf"] < ranges["length"] and 0 < ranges["min"] <= ranges["max"] <= reach


def check_image(msg: dict[str, Any], key: str) -> None:
    assert msg["encoding"] == "rgb8" and msg["step"] == 3 * msg["width"]
    assert msg["data"]["length"] == msg["step"] * msg["height"] and msg["data"]["dtype"] == "uint8"
    if key != "camera_360/image_raw":
        assert (msg["width"], msg["height"], msg["header"]["frame_id"]) == (WIDTH, HEIGHT, f"{key}_optical_frame")


def check_camera_info(msg: dict[str, Any], key: str) -> None:
    fx, cx = msg["k"][0], msg["k"][2]
    if key == "camera_360/camera_info":
        assert fx > 0 and 0 <= cx < msg["width"]
        return
    assert (msg["width"], msg["height"]) == (WIDTH, HEIGHT)
    assert fx == pytest.approx((WIDTH / 2) / math.tan(HFOV / 2), rel=1e-4) and cx == pytest.approx((WIDTH - 1) / 2)


def check_pose(msg: dict[str, Any], key: str) -> None:
    position = msg["pose"]["position"]
    expected = SPAWN if key == "model/flexley_tug/pose" else TROLLEY
    assert msg["header"]["frame_id"] == "world"
    assert math.hypot(position["x"] - expected[0], position["y"] - expected[1]) < POSE_TOLERANCE


CHECKS: dict[str, Callable[[dict[str, Any], str], None]] = {
    CLOCK: check_clock,
    ODOMETRY: check_odometry,
    TF: check_tf,
    STRING: check_string,
    JOINT_STATE: check_joint_state,
    IMU: check_imu,
    LASER_SCAN: check_scan,
    IMAGE: check_image,
    CAMERA_INFO: check_camera_info,
    POSE_STAMPED: check_pose,
}


@dataclass(frozen=True)
class Echoes:
    """What `echo KEY --once --json` printed for each output, and the server's sim time (ns) read
    just before they started and just after the last ended."""

    results: dict[str, subprocess.CompletedProcess[str]]
    sim_ns: tuple[int, int]


def sim_ns(sim: SimServer) -> int:
    return round(float(sim.state()["sim_time"]) * 1e9)


@pytest.fixture(scope="module", name="echoes")
def echoes_fixture(sim: SimServer, table: dict[str, dict[str, str]]) -> Echoes:
    """`echo KEY --once --json` of every output there is, all at once (each waits for its first message)."""
    before = sim_ns(sim)
    processes = {
        key: subprocess.Popen(
            client_command("echo", *bus_args(sim), key, "--once", "--json", "--wait", ECHO_WAIT_S),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )
        for key in OUTPUTS
    }
    results = {}
    for key, process in processes.items():
        out, err = process.communicate(timeout=RUN_TIMEOUT_S)
        results[key] = subprocess.CompletedProcess(process.args, process.returncode, out, err)
    return Echoes(results, (before, sim_ns(sim)))


@pytest.mark.parametrize("key", OUTPUTS)
def test_echo_decodes_one_message_of_each_output(echoes: Echoes, key: str) -> None:
    result = echoes.results[key]
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 1, f"--once --json prints one line: {result.stdout[:500]}"
    CHECKS[KEYS[key][0]](json.loads(lines[0]), key)


def test_echo_reads_the_servers_sim_time_on_clock(echoes: Echoes) -> None:
    """The clock echo prints is the server's sim time while it ran: after the sim time read before
    the echoes started, before the one read after they ended."""
    result = echoes.results["clock"]
    assert result.returncode == 0, result.stderr
    before, after = echoes.sim_ns
    assert before <= clock_ns(json.loads(result.stdout)) <= after, (before, result.stdout, after)


def test_echo_decodes_what_is_sent_to_the_inputs(sim: SimServer) -> None:
    """cmd_vel, attach and detach have no publisher until someone sends: echo waits for it, then decodes it.
    Attach then detach (the trolley is fixed where it stands, then freed): the latched state follows."""
    sent = {
        "cmd_vel": messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        "attach": messages.empty(),
        "detach": messages.empty(),
    }
    with client_process(sim, "echo", "detachable_joint/state", "--json") as states:
        wait_until(lambda: states.stdout().count("\n") >= 1, timeout=RUN_TIMEOUT_S, what="the latched state")
        for key, msg in sent.items():
            with client_process(sim, "echo", key, "--once", "--json") as echo:

                def echoed(key: str = key, msg: Any = msg, echo: Any = echo) -> bool:
                    sim.send(key, msg)
                    return not echo.alive()

                wait_until(
                    echoed,
                    timeout=RUN_TIMEOUT_S,
                    what=f"echo of {key}",
                    poll=0.2,
                )
                assert echo.process.wait() == 0, echo.stderr()
                decoded = json.loads(echo.stdout())
            if key == "cmd_vel":
                assert decoded["linear"] == decoded["angular"] == {"x": 0.0, "y": 0.0, "z": 0.0}
            else:
                assert decoded == {"structure_needs_at_least_one_member": 0}
        wait_until(lambda: states.stdout().count("\n") >= 3, timeout=RUN_TIMEOUT_S, what="the state's changes")
        assert [json.loads(line)["data"] for line in states.stdout().splitlines()] == [
            "detached",
            "attached",
            "detached",
        ]


# --- echo: text, late joiners, streams, mistakes --------------------------------------------


def test_echo_summarises_the_720_ranges_of_a_scan(sim: SimServer) -> None:
    result = run(sim, "echo", "lidar_front", "--once")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-1] == "---"
    assert "frame_id: base_scan_front" in result.stdout
    found = re.search(
        r"^ranges: <720 × float32: min ([0-9.]+), max ([0-9.]+), (\d+) inf, 0 nan>$", result.stdout, re.MULTILINE
    )
    assert found, result.stdout
    assert 0.08 <= float(found[1]) <= float(found[2]) <= 10.0 and int(found[3]) < 720


def test_echo_full_json_writes_every_range_with_inf_as_a_string(sim: SimServer) -> None:
    result = run(sim, "echo", "lidar_front", "--once", "--json", "--full")
    assert result.returncode == 0, result.stderr
    ranges = json.loads(result.stdout)["ranges"]
    assert len(ranges) == 720
    assert {r for r in ranges if isinstance(r, str)} == {"inf"}  # the warehouse leaves most rays without a return
    assert all(0.08 <= r <= 10.0 for r in ranges if not isinstance(r, str))


def test_echo_gives_a_late_joiner_the_whole_robot_description(sim: SimServer) -> None:
    result = run(sim, "echo", "robot_description", "--once")
    assert result.returncode == 0, result.stderr
    assert re.match(r'data: "<\?xml .*\.\.\. \(\d+ characters; --full prints all\)"\n---\n$', result.stdout), (
        result.stdout[:300]
    )
    full = run(sim, "echo", "robot_description", "--once", "--json", "--full")
    urdf = ET.fromstring(json.loads(full.stdout)["data"])
    assert urdf.tag == "robot" and urdf.get("name") == "flexley_tug"
    assert {"base_footprint", "base_link", "imu_link", "base_scan_front", "base_scan_back"} <= {
        link.get("name") for link in urdf.iter("link")
    }


def test_echo_streams_until_sigterm_and_exits_0(sim: SimServer) -> None:
    with client_process(sim, "echo", "imu_scan") as echo:
        wait_until(lambda: echo.stdout().count("\n---\n") >= 5, timeout=RUN_TIMEOUT_S, what="five IMU messages")
        code = echo.stop()
        text = echo.stdout()
    assert code == 0, text[-500:]
    blocks = [block for block in text.split("---\n") if block.strip()]
    stamps = [re.search(r"sec: (\d+)\n\s+nanosec: (\d+)", block) for block in blocks]
    times = [int(m[1]) * 10**9 + int(m[2]) for m in stamps if m]
    assert len(times) >= 5 and times == sorted(times) and len(set(times)) == len(times)


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("no_such_key", r"key 'no_such_key': nothing publishes or subscribes to it"),
        ("lidar", r"similar: .*lidar_front"),
    ],
)
def test_echo_of_an_unknown_key_is_one_line_and_exit_2(sim: SimServer, key: str, expected: str) -> None:
    result = run(sim, "echo", key, "--wait", "1")
    assert result.returncode == 2
    assert result.stdout == "" and result.stderr.count("\n") == 1 and re.search(expected, result.stderr), result.stderr


def test_echo_of_a_service_is_one_line_and_exit_2(sim: SimServer) -> None:
    result = run(sim, "echo", f"world/{sim.world}/state", "--wait", "1")
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "service" in result.stderr, result.stderr


def test_echo_of_an_invalid_key_is_one_line_and_exit_2(sim: SimServer) -> None:
    result = run(sim, "echo", "lidar*")
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "invalid topic 'lidar*'" in result.stderr and "special character" in result.stderr
