"""`simbot launch --zones 2` on loopback: one kinematic fleet of four tugs split across two zone servers
in lockstep, launch as the Zenoh router that joins them, and its handover watching the whole fleet.

With `--spawn 0 0 0.1 0` and one column per zone the tugs stand at x 0 (tug_1, tug_3) and x 5
(tug_2, tug_4), so the boundary lies halfway, at x 2.5. tug_1 is driven at 0.5 m/s for 5.4 s on
its own key `tug_1/cmd_vel`: kinematic mode moves it exactly 2.7 m (tests/test_kinematic.py),
over the boundary and 0.2 m short of tug_2's tail (a tug is 2.1 m long). World control answers
between steps, so the handover may take it while zone_1 is still stepping: it must create it in
zone_2 where it stood, past the boundary and at most 2.7 m from where it began (±1 cm: the pose
crosses as world state's floats, and as the handover prints it), and remove it from zone_1; the
same key then drives it 0.1 m on in zone_2 (its front still short of tug_2's tail). Killing zone_2 is reported with its signal
and zone_1 keeps stepping: 100 steps of 5 ms are 0.5 s of its sim time.
"""

from __future__ import annotations

import math
import os
import signal
import time
from typing import Any

import pytest
from server_helpers import SEND_TIMEOUT_S, planar_distance, wait_until
from test_client_launch import START_TIMEOUT_S, Launch, launched, run_launch

from simbot.bus import Node, messages

STEP_S = 0.005
FLEET = "--robots 4 --physics kinematic --mode lockstep --spawn 0 0 0.1 0 --quiet"
RESEND_S = 1.0
HANDOVER_TIMEOUT_S = 60.0
"""Loading a tug with its sensors takes a second or two; a loaded machine, more."""


class Zones:
    """World control of each zone of a launch, and the fleet's commands, on one client node."""

    def __init__(self, launch: Launch, node: Node) -> None:
        self.launch, self.node = launch, node
        self.cmd_vel = node.publisher("tug_1/cmd_vel", messages.Twist, drop=False)

    def call(self, zone: str, service: str, request: dict[str, Any]) -> dict[str, Any]:
        reply = self.node.call(f"{zone}/world/empty/{service}", request, timeout=60.0)
        assert reply.get("ok") is True, reply
        return reply

    def models(self, zone: str) -> dict[str, Any]:
        return dict(self.call(zone, "state", {})["models"])

    def step(self, zone: str, steps: int) -> float:
        """`steps` steps of `zone`; its sim time after them."""
        return float(self.call(zone, "control", {"multi_step": steps})["sim_time"])

    def drive(self, zone: str, speed: float) -> None:
        """tug_1's command on its own key, put again each RESEND_S until `zone` (the one holding it)
        has received it: a robot just created there may not be routed to this session yet (the
        same twist twice before a step is the same command)."""
        key = f"{self.launch.namespace}/tug_1/cmd_vel"
        before = self.call(zone, "state", {})["received"][key]
        deadline = time.monotonic() + SEND_TIMEOUT_S
        while True:
            self.cmd_vel.put(messages.twist((speed, 0.0, 0.0), (0.0, 0.0, 0.0)))
            try:
                wait_until(lambda: self.call(zone, "state", {})["received"][key] > before, RESEND_S, "cmd_vel")
                return
            except AssertionError:
                if time.monotonic() > deadline:
                    raise AssertionError(f"{zone} did not receive tug_1/cmd_vel within {SEND_TIMEOUT_S} s") from None


def x_of(models: dict[str, Any], name: str) -> float:
    return float(models[name]["position"][0])


def test_zones_split_the_fleet_hand_a_robot_over_and_outlive_each_other() -> None:
    with launched("--world", "empty", "--zones", "2", f"--server-args={FLEET}") as launch:
        launch.wait_line(r"^\[launch\] started handover \(pid \d+\)$", START_TIMEOUT_S * 2)
        with launch.client() as node:
            zones = Zones(launch, node)
            one, two = zones.models("zone_1"), zones.models("zone_2")
            assert {n for n in one if n.startswith("tug_")} == {"tug_1", "tug_3"}
            assert {n for n in two if n.startswith("tug_")} == {"tug_2", "tug_4"}
            assert [x_of(one, "tug_1"), x_of(two, "tug_2")] == pytest.approx([0.0, 5.0], abs=1e-6)

            zones.drive("zone_1", 0.5)
            zones.step("zone_1", round(5.4 / STEP_S))  # the handover may act at once: its line has the pose
            line = launch.wait_line(r"^\[handover\] tug_1: zone_1 → zone_2 at x (\S+) y (\S+)$", HANDOVER_TIMEOUT_S)
            crossed = (float(line[1]), float(line[2]))
            assert 2.5 <= crossed[0] <= 2.71 and abs(crossed[1]) < 0.01, crossed
            assert "tug_1" not in zones.models("zone_1")
            arrived = zones.models("zone_2")["tug_1"]["position"]
            assert planar_distance(crossed, arrived) < 0.01, (crossed, arrived)

            zones.drive("zone_2", 0.2)  # the same key, now zone_2's robot
            zones.step("zone_2", round(0.5 / STEP_S))
            moved = zones.models("zone_2")["tug_1"]["position"]
            assert planar_distance(arrived, moved) == pytest.approx(0.1, abs=0.005), (arrived, moved)

            os.kill(launch.pids()["zone_2"], signal.SIGKILL)
            launch.wait_line(r"^\[launch\] zone_2 exited with signal SIGKILL$")
            launch.wait_line(r"^\[launch\] zone_2 is gone with the robots it held; still running: zone_1$")
            before = float(zones.call("zone_1", "state", {})["sim_time"])
            assert math.isclose(zones.step("zone_1", 100) - before, 100 * STEP_S, abs_tol=1e-9)
            assert launch.process.poll() is None

        launch.process.send_signal(signal.SIGINT)
        assert launch.wait_exit() == 0, launch.output()[-3000:]
        for name in ("zone_1", "handover"):
            assert f"[launch] {name} exited with code 0" in launch.output()


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--zone", "a:-inf:0", "--zone", "b:0:1"], "--zone: tug_2 stands at x 5, in no zone"),
        (["--zone", "a:-inf:1", "--zone", "b:0:inf"], "--zone: zones a and b overlap from x 0 to 1"),
        (["--zones", "3", "--server-args=--robots 2"], "--zones 3: 3 zones need robots at 3 different x at least"),
        (["--zones", "2", "--server-args=--mode fast"], "--zones: zones split a fleet"),
    ],
)
def test_zones_that_leave_a_robot_out_are_one_line_and_exit_2(args: list[str], expected: str) -> None:
    fleet = [] if any(a.startswith("--server-args") for a in args) else ["--server-args=--robots 4 --spawn 0 0 0.1 0"]
    result = run_launch(*args, *fleet)
    assert result.returncode == 2 and result.stdout == "", result
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert result.stderr.startswith(f"simbot launch: error: {expected}"), result.stderr


def test_no_zones_is_argparses_line_naming_the_option() -> None:
    result = run_launch("--zones", "0", "--server-args=--robots 4")
    assert result.returncode == 2 and result.stdout == ""
    assert (
        result.stderr.splitlines()[-1] == "simbot launch: error: argument --zones: expected a whole number ≥ 1, got '0'"
    )
