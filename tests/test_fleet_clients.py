"""Clients following one robot of a fleet: `--robot-namespace tug_2` (issue 17, item 2).

A lockstep server with `--robots 2` (tug_1 at y 0, tug_2 at y 1.5) and a 0.5 m cube of the test's
own, tall enough for the lidars' plane, 3 m ahead of tug_2's front lidar. The teleop client
follows tug_2: it reads tug_2's front lidar through tug_2's prefixed frames (the cube 3.00 m
ahead: the path's nearest return, quantised to 0.01 m) and drives tug_2 on `tug_2/cmd_vel`
while tug_1 stays (< 1 cm). The merger merges tug_2's scans into `tug_2/scan` in
`tug_2/base_link`: straight ahead, the cube's face lies at its distance from base_link's
origin, within the merger's 0.03 m (its bins are 0.25°, the face square to the bearing).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterator

import pytest
from client_helpers import bus_args, client_command, client_process, pty_client
from server_helpers import TWIST, SimServer, planar_distance, running_server
from test_fleet_spawn import MAST, MAST_HALF, SCAN, _pose

ROBOT = ("--robot-namespace", "tug_2")
LIDAR_X = 0.99
MERGED_BINS = 1440
WAIT_S = 60.0


@pytest.fixture(scope="module", name="sim")
def two_tugs() -> Iterator[SimServer]:
    extra = ("--robots", "2", "--spawn", "0", "0", "0.1", "0", "--camera-size", "8x6", "--camera-rate", "1")
    with running_server("empty", extra=extra) as sim:
        sim.step(300)
        (x, y, _), _ = sim.pose("tug_2")
        reply = sim.call(
            "create", {"sdf": MAST, "name": "mast", "pose": _pose(x + LIDAR_X + 3.0 + MAST_HALF, y, MAST_HALF)}
        )
        assert reply["ok"] is True
        yield sim


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
        sim.step(1000)
        client.type("q")
        client.wait_exit()
    moved = {name: planar_distance(before[name], sim.pose(name)[0]) for name in before}
    print(f"\nteleop on tug_2: tug_2 moved {moved['tug_2']:.3f} m, tug_1 {moved['tug_1']:.4f} m")
    assert moved["tug_2"] > 0.3 and moved["tug_1"] < 0.01
