"""Kinematic fleet mode (simbot.sim.physics.kinematic_world) on a real server in lockstep.

A kinematic base moves by exactly what its drive commands (the tug's DiffDrive states no limits),
integrated at the world's 5 ms step with the heading at each step's midpoint, so the figures are
exact up to float rounding: 0.5 m/s for 2 s is 1.0 m and 0.5 rad/s for 2 s is 1.0 rad; the ±1 %
leaves room for nothing but rounding. The wall world asks for the mode in its SDF
(`<physics type="kinematic">`); the fleet test asks on the command line (`--physics kinematic`).
"""

from __future__ import annotations

import math
from pathlib import Path

from server_helpers import SimServer, module_server, planar_distance, reset_before_each, running_server

from simbot.bus import messages
from simbot.transform import yaw_of

STEP_S = 0.005
WALL_FACE_X = 4.0
"""tests/fixtures/kinematic_wall.sdf: the wall's near face; the tug starts at the origin facing it."""

WORLD = str(Path(__file__).parent / "fixtures" / "kinematic_wall.sdf")
sim = module_server(WORLD, extra=("--spawn", "0", "0", "0.1", "0"))
fresh_world = reset_before_each()


def _steps(seconds: float) -> int:
    return round(seconds / STEP_S)


def test_moves_the_commanded_distance(sim: SimServer) -> None:
    """0.5 m/s for 2 s: 1.0 m ± 1 %, straight ahead."""
    start, _ = sim.pose()
    sim.drive(0.5)
    sim.step(_steps(2.0))
    sim.drive(0.0)
    sim.step(1)
    end, quat = sim.pose()
    assert abs(planar_distance(start, end) - 1.0) <= 0.01, (start, end)
    assert abs(end[1] - start[1]) < 1e-6 and abs(yaw_of(quat)) < 1e-6


def test_turns_at_the_commanded_rate(sim: SimServer) -> None:
    """0.5 rad/s for 2 s on the spot: 1.0 rad ± 1 %, not moving off it."""
    start, _ = sim.pose()
    sim.drive(0.0, 0.5)
    sim.step(_steps(2.0))
    sim.drive(0.0, 0.0)
    sim.step(1)
    end, quat = sim.pose()
    assert abs(yaw_of(quat) - 1.0) <= 0.01
    assert planar_distance(start, end) < 1e-3


def test_stops_at_a_wall_without_passing_it(sim: SimServer) -> None:
    """Driven at the wall for 10 s (5 m of command for 4 m of room, less the tug's front): it stops short of the face,
    after covering most of the room, and stays stopped while still commanded."""
    start, _ = sim.pose()
    sim.drive(0.5)
    sim.step(_steps(10.0))
    stopped, _ = sim.pose()
    sim.step(_steps(1.0))
    still, _ = sim.pose()
    sim.drive(0.0)
    assert stopped[0] < WALL_FACE_X, stopped
    assert stopped[0] - start[0] > 2.0, (start, stopped)
    assert planar_distance(stopped, still) < 1e-9
    assert "stopped by contact with wall" in sim.stderr()


def test_a_hundred_tugs_step() -> None:
    """`--physics kinematic --robots 100`: the world loads and steps, and the last tug drives."""
    extra = ("--physics", "kinematic", "--robots", "100", "--spawn", "0", "0", "0.1", "0")
    with running_server("empty", extra=extra) as fleet:
        state = fleet.state()
        assert {f"tug_{i}" for i in range(1, 101)} <= set(state["models"])
        start, _ = fleet.pose("tug_100", state)
        fleet.send("tug_100/cmd_vel", messages.twist((0.5, 0.0, 0.0), (0.0, 0.0, 0.0)))
        fleet.step(_steps(0.2))
        end, _ = fleet.pose("tug_100")
        assert math.isclose(planar_distance(start, end), 0.1, rel_tol=0.01), (start, end)


def test_docking_carries_the_trolley() -> None:
    """The warehouse's docking (tests/test_server_docking.py) kinematically: driven 3.5 m under the
    trolley, attached, 1 m of pull moves the trolley exactly as the tug (1 cm), detached it stays."""
    with running_server("warehouse", extra=("--physics", "kinematic")) as dock:
        trolley0, _ = dock.pose("trolley")
        _drive_for(dock, 0.5, 7.0)
        (trolley1, _), (robot1, _) = dock.pose("trolley"), dock.pose()
        assert abs(robot1[0] - trolley1[0]) < 0.15 and planar_distance(trolley0, trolley1) < 1e-6
        dock.send("attach", messages.empty())
        _drive_for(dock, 0.5, 2.0)
        (trolley2, _), (robot2, _) = dock.pose("trolley"), dock.pose()
        assert abs(planar_distance(trolley1, trolley2) - planar_distance(robot1, robot2)) < 0.01
        assert abs(planar_distance(robot1, robot2) - 1.0) < 0.01
        dock.send("detach", messages.empty())
        _drive_for(dock, 0.5, 1.0)
        (trolley3, _), (robot3, _) = dock.pose("trolley"), dock.pose()
        assert planar_distance(trolley2, trolley3) < 1e-6 and abs(planar_distance(robot2, robot3) - 0.5) < 0.01


def _drive_for(sim: SimServer, speed: float, seconds: float) -> None:
    sim.drive(speed)
    sim.step(_steps(seconds))
    sim.drive(0.0)
    sim.step(1)
