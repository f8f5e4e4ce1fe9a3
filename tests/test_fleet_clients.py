"""Clients following one robot of a fleet: `--robot-namespace tug_2` (issue 17, item 2).

A lockstep server with `--robots 2` (tug_1 at y 0, tug_2 at y 1.5; cameras 8 × 6 at 10 Hz) and a
0.5 m cube of the test's own, tall enough for the lidars' plane, 3 m ahead of tug_2's front
lidar. Each client follows tug_2, and each test shows that it does and that tug_1 is left alone:
- teleop reads tug_2's front lidar through tug_2's prefixed frames (the cube 3.00 m ahead: the
  path's nearest return, quantised to 0.01 m) and drives tug_2 on `tug_2/cmd_vel` at its 0.5 m/s
  (±5 %, straight) while tug_1 stays (< 1 cm).
- the merger merges tug_2's scans into `tug_2/scan` in `tug_2/base_link`: straight ahead, the
  cube's face lies at its distance from base_link's origin, within the merger's 0.03 m (its bins
  are 0.25°, the face square to the bearing).
- dock, with a trolley created over tug_2 (0.2 m to its side, as tests/test_client_dock.py spawns
  the one robot), sees it near and attaches it to tug_2 (`tug_2/detachable_joint/state`); tug_2
  then pulls it (the trolley moves as tug_2 does, within 2 cm, as in the server's docking test)
  while tug_1 stays; tug_1's own attach is refused, since tug_2 holds the trolley.
- the stitcher's strip is tug_2's six images side by side, byte for byte, at their stamp (not
  tug_1's: those differ), in tug_2's camera frame; its cylinder is stamped in `tug_2/base_link`.
- the monitor lists tug_2's keys by their names in its namespace, its sensors at their nominal
  rates against the world's clock (tests/test_client_monitor.py's tolerance), its scans in its
  frames, its ground truth where the world state has it, and tug_2's cameras only; none of tug_1.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from client_helpers import bus_args, client_command, client_process, pty_client
from conftest import TROLLEY_SDF
from server_helpers import STRING, TWIST, Collector, SimServer, planar_distance, running_server, wait_until
from test_client_monitor import BLOCKS, LIDAR_HZ, POSE_TOLERANCE, check_rate, numbers, parse_block
from test_client_stitcher import CAMERA_Z, HFOV, RADIUS, check_info, info_of, run_stitcher
from test_fleet_spawn import MAST, MAST_HALF, SCAN, _pose

from simbot.bus import messages
from simbot.clients.stitcher import CAMERAS, IMAGE

ROBOT = ("--robot-namespace", "tug_2")
LIDAR_X = 0.99
MERGED_BINS = 1440
WAIT_S = 60.0
WIDTH, HEIGHT = 8, 6
CAMERA_STEPS = 100
"""One camera period at 10 Hz, in 1 ms steps."""
TELEOP_SPEED, TELEOP_SPEED_REL = 0.5, 0.05
"""teleop's `w` (its default --speed), which the tug holds within 5 % once up to speed
(tests/test_client_teleop.py: it settles within 0.1 s)."""
UP_TO_SPEED_STEPS = 200
"""0.2 s from the step the command was seen after: the tug is at speed before it is timed."""
STRAIGHT_M = 0.01
"""How far across its heading a tug driving straight for 1 s may drift (its wheels' skid)."""
TROLLEY_OFFSET = 0.2
ATTACHED_TOLERANCE = 0.02


@pytest.fixture(scope="module", name="sim")
def two_tugs() -> Iterator[SimServer]:
    extra = (
        "--robots",
        "2",
        "--spawn",
        "0",
        "0",
        "0.1",
        "0",
        "--camera-size",
        f"{WIDTH}x{HEIGHT}",
        "--camera-rate",
        "10",
    )
    with running_server("empty", extra=extra) as sim:
        sim.step(300)
        (x, y, _), _ = sim.pose("tug_2")
        reply = sim.call(
            "create", {"sdf": MAST, "name": "mast", "pose": _pose(x + LIDAR_X + 3.0 + MAST_HALF, y, MAST_HALF)}
        )
        assert reply["ok"] is True
        yield sim


@pytest.fixture(autouse=True)
def unsubscribed(sim: SimServer) -> Iterator[None]:
    """A test's collectors do not outlive it (a camera subscribed to goes on rendering)."""
    yield
    sim.unsubscribe_all()


def step_until(sim: SimServer, done: Callable[[], object], what: str) -> None:
    """Lockstep: 100 steps at a time until `done()` (a client on the bus sees what those steps sent)."""
    deadline = time.monotonic() + WAIT_S
    while not done():
        assert time.monotonic() < deadline, f"no {what} within {WAIT_S} s"
        sim.step(100)
        time.sleep(0.05)


def test_merger_merges_the_followed_robots_scans(sim: SimServer) -> None:
    merged = sim.subscribe("tug_2/scan", SCAN)
    with client_process(sim, "merger", *ROBOT):
        step_until(sim, lambda: len(merged) >= 2, "merged scan on tug_2/scan")
    scan = merged.messages()[-1]
    (x, _, _), _ = sim.pose("tug_2")
    (mast_x, _, _), _ = sim.pose("mast")
    assert scan.header.frame_id == "tug_2/base_link" and len(scan.ranges) == MERGED_BINS
    ahead = scan.ranges[MERGED_BINS // 2]
    print(f"\ntug_2/scan straight ahead: {ahead:.3f} m (the cube's face {mast_x - MAST_HALF - x:.3f} m)")
    assert ahead == pytest.approx(mast_x - MAST_HALF - x, abs=0.03)


def test_teleop_reads_and_drives_the_followed_robot(sim: SimServer) -> None:
    commands = sim.subscribe("tug_2/cmd_vel", TWIST)
    with pty_client(client_command("teleop", *bus_args(sim), *ROBOT)) as client:
        step_until(sim, lambda: re.search(r"ahead \d+\.\d+ m", client.screen()), "status line with the cube ahead")
        assert re.search(r"ahead 3\.0\d m", client.screen()), client.screen()[-500:]
        before = {name: sim.pose(name)[0] for name in ("tug_1", "tug_2")}
        client.type("w")
        step_until(sim, lambda: any(m.linear.x > 0.4 for m in commands.messages()), "w on tug_2/cmd_vel")
        sim.step(UP_TO_SPEED_STEPS)
        start, start_s = sim.pose("tug_2")[0], float(sim.state()["sim_time"])
        sim.step(1000)
        end, end_s = sim.pose("tug_2")[0], float(sim.state()["sim_time"])
        client.type("q")
        client.wait_exit()
    moved = {name: planar_distance(before[name], sim.pose(name)[0]) for name in before}
    speed = planar_distance(start, end) / (end_s - start_s)
    print(f"\nteleop on tug_2: tug_2 drove at {speed:.4f} m/s, tug_1 moved {moved['tug_1']:.4f} m")
    assert speed == pytest.approx(TELEOP_SPEED, rel=TELEOP_SPEED_REL), f"tug_2 drove at {speed:.4f} m/s"
    assert abs(end[1] - start[1]) < STRAIGHT_M, "tug_2 drove straight ahead, along x"
    assert moved["tug_1"] < 0.01


def _last(states: Collector[Any]) -> str | None:
    """The joint's latest state (`attached` / `detached`), None before the latched one came."""
    received = states.messages()
    return str(received[-1].data) if received else None


def _drive_tug_2(sim: SimServer, speed: float, steps: int) -> None:
    """tug_2 at `speed` for `steps`, then stopped and brought to rest (its wheels' servos stop it in well under 0.5 s)."""
    sim.send("tug_2/cmd_vel", messages.twist((speed, 0.0, 0.0), (0.0, 0.0, 0.0)))
    sim.step(steps)
    sim.send("tug_2/cmd_vel", messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    sim.step(500)


def test_dock_attaches_the_trolley_to_the_followed_robot(sim: SimServer) -> None:
    (x, y, _), _ = sim.pose("tug_2")
    trolley = {"sdf_filename": str(TROLLEY_SDF), "name": "trolley", "pose": _pose(x, y + TROLLEY_OFFSET, 0.0)}
    assert sim.call("create", trolley)["ok"] is True
    try:
        joints = {
            tug: sim.subscribe(f"{tug}/detachable_joint/state", STRING, latched=True) for tug in ("tug_1", "tug_2")
        }
        with pty_client(client_command("dock", *bus_args(sim), *ROBOT)) as client:
            step_until(sim, lambda: "trolley near (0.20 m apart)" in client.screen(), "tug_2 near the trolley")
            client.type("t")
            step_until(sim, lambda: _last(joints["tug_2"]) == "attached", "'attached' on tug_2/detachable_joint/state")
            sim.send("tug_1/attach", messages.empty())  # tug_1 asks for the trolley tug_2 holds
            sim.step(10)
            wait_until(lambda: "cannot attach: trolley is attached to tug_2" in sim.stderr(), 10.0, "tug_1 refused")
            before = {name: sim.pose(name)[0] for name in ("tug_1", "tug_2", "trolley")}
            _drive_tug_2(sim, 0.5, 1000)
            moved = {name: planar_distance(before[name], sim.pose(name)[0]) for name in before}
            mark = client.mark()
            client.type("r")
            step_until(sim, lambda: _last(joints["tug_2"]) == "detached", "'detached' on tug_2/detachable_joint/state")
            client.wait_for(r"joint detached", since=mark)
            client.type("q")
            assert client.wait_exit() == 0
    finally:
        sim.call("remove", {"name": "trolley"})
    print(
        f"\ndock on tug_2: tug_2 drove {moved['tug_2']:.3f} m pulling the trolley {moved['trolley']:.3f} m; "
        f"tug_1 moved {moved['tug_1']:.4f} m"
    )
    assert [m.data for m in joints["tug_1"].messages()] == ["detached"]
    assert moved["tug_2"] > 0.3 and abs(moved["trolley"] - moved["tug_2"]) < ATTACHED_TOLERANCE
    assert moved["tug_1"] < 0.01


def test_stitcher_strip_is_the_followed_robots_six_images(sim: SimServer) -> None:
    raw = {tug: {name: sim.subscribe(f"{tug}/{name}", IMAGE) for name in CAMERAS} for tug in ("tug_1", "tug_2")}
    images, infos, _ = run_stitcher(sim, "--layout", "strip", robot="tug_2", frame_steps=CAMERA_STEPS)
    panorama = images[-1]
    fx = (WIDTH / 2) / math.tan(HFOV / 2)
    check_info(
        panorama,
        info_of(panorama, infos),
        "tug_2/camera_front_optical_frame",
        (fx, fx, (WIDTH - 1) / 2, (HEIGHT - 1) / 2),
    )
    stamp = messages.stamp_ns(panorama.header)
    strips = {
        tug: np.hstack([messages.image_pixels(cameras[name].wait_stamp(stamp)) for name in CAMERAS])
        for tug, cameras in raw.items()
    }
    pixels = messages.image_pixels(panorama)
    assert np.array_equal(pixels, strips["tug_2"]), "the strip is not tug_2's six images at its stamp"
    assert not np.array_equal(pixels, strips["tug_1"]), "tug_1's images are tug_2's: the test tells nothing"


def test_stitcher_cylinder_is_in_the_followed_robots_base_link(sim: SimServer) -> None:
    images, infos, _ = run_stitcher(sim, robot="tug_2", frame_steps=CAMERA_STEPS)
    panorama = images[-1]
    width = 3 * WIDTH
    f = width / (2 * math.pi)
    k = (f, f, (width - 1) / 2, (HEIGHT - 1) / 2 + f * CAMERA_Z / RADIUS)  # cy: all six placed by tug_2's tf_static
    check_info(panorama, info_of(panorama, infos), "tug_2/base_link", k)
    assert messages.image_pixels(panorama).any()


def test_monitor_lists_the_followed_robots_sensors_at_their_rates(sim: SimServer) -> None:
    with client_process(sim, "monitor", *ROBOT) as monitor:
        wait_until(
            lambda: sim.step(10) and monitor.stdout().count("\n\n") >= BLOCKS, WAIT_S, f"{BLOCKS} tables", poll=0.0
        )
        text = monitor.stdout()
    _, rows = parse_block(text.split("\n\n")[BLOCKS - 1])
    print(f"\nmonitor on tug_2: {', '.join(f'{key} {rate}' for key, (rate, _) in rows.items())}")
    assert not [key for key in rows if "tug_1" in key], rows.keys()
    for key, nominal in (
        ("lidar_front", LIDAR_HZ),
        ("lidar_back", LIDAR_HZ),
        ("odom", 50.0),
        ("imu_scan", 200.0),
        ("joint_states", 30.0),
    ):
        check_rate(rows, key, "/clock", nominal)
    for key, frame in (("lidar_front", "tug_2/base_scan_front"), ("lidar_back", "tug_2/base_scan_back")):
        assert rows[key][1].endswith(f"({frame})"), rows[key]
    (x, y, _), _ = sim.pose("tug_2")
    shown = numbers(rows["/model/tug_2/pose"][1])[:2]
    assert math.hypot(shown[0] - x, shown[1] - y) <= POSE_TOLERANCE, rows["/model/tug_2/pose"]
    assert {f"tug_2/base_link/{camera}" for camera in CAMERAS} <= set(rows)
