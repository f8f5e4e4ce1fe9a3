"""`simbot handover` on loopback: two kinematic zone servers, site_a (x < 2) and site_b (x ≥ 2), and a
Zenoh router (docker/zenoh_router.py, a Python session in router mode: zenohd may not be installed)
that the client alone connects to.

tug_1 starts in site_a at the origin and is driven at 0.5 m/s for 5 s: kinematic mode moves it
exactly 2.5 m (tests/test_kinematic.py), over the boundary. The client must then create it in
site_b at that pose (±1 cm: the pose crosses as world state's floats) and remove it from site_a;
in site_b it drives again on its own keys.
"""

from __future__ import annotations

import subprocess

from bus_helpers import free_port
from client_helpers import client_command
from conftest import REPO
from server_helpers import SimServer, planar_distance, router, running_server, wait_until

from simbot.bus import messages

KINEMATIC = ("--physics", "kinematic", "--spawn", "0", "0", "0.1", "0")
STEP_S = 0.005


def _drive(zone: SimServer, speed: float) -> None:
    zone.send("tug_1/cmd_vel", messages.twist((speed, 0.0, 0.0), (0.0, 0.0, 0.0)))


def test_a_robot_crossing_the_boundary_moves_to_the_next_zone() -> None:
    with (
        running_server(extra=(*KINEMATIC, "--robots", "1")) as site_a,
        running_server(extra=(*KINEMATIC, "--robot", "none")) as site_b,
        router(free_port(), [site_a, site_b]) as at,
    ):
        _drive(site_a, 0.5)
        site_a.step(round(5.0 / STEP_S))
        crossed, _ = site_a.pose("tug_1")
        zones = ["--zone", f"{site_a.namespace}:-inf:2", "--zone", f"{site_b.namespace}:2:inf"]
        command = client_command("handover", "tug_1", *zones, "--world", "empty", "--once", "--connect", at)
        done = subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=120, check=False)
        assert done.returncode == 0, done.stderr
        assert f"tug_1: {site_a.namespace} → {site_b.namespace}" in done.stdout
        assert "tug_1" not in site_a.state()["models"]
        arrived, _ = site_b.pose("tug_1")
        assert abs(crossed[0] - 2.5) < 0.01 and planar_distance(crossed, arrived) < 0.01, (crossed, arrived)
        wait_until(lambda: site_b.key("tug_1/cmd_vel") in site_b.state()["received"], 30.0, "tug_1's cmd_vel in site_b")
        _drive(site_b, 0.5)
        site_b.step(round(1.0 / STEP_S))
        moved, _ = site_b.pose("tug_1")
        assert abs(planar_distance(arrived, moved) - 0.5) < 0.005, (arrived, moved)


def test_a_bad_zone_is_one_line_and_exit_2() -> None:
    done = subprocess.run(
        client_command("handover", "tug_1", "--zone", "site_a:5:1"), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and done.stderr.strip().splitlines()[-1].endswith("got 'site_a:5:1'")
