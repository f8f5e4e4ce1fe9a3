"""simbot-teleop in a pseudo-terminal, driving the robot of a real server in real time.

The world is `tests/fixtures/teleop_boxes.sdf`: an open lane at y 0 (the robot's spawn point,
(−2.5, 0)), a box across the lane at y 4 (its face at x 2.0) and a wall beside the lane at y −4
(0.15 m from the robot's flank, outside the path corridor but 0.42 m from the front lidar).

The client runs on wall time and the server in real time, whose factor can drop below 1 on a
loaded machine, so speeds are measured against the sim time of the world state, never the wall
clock: the robot settles at 0.5 m/s within 0.1 s (the README's 2.00 m in 4 s), hence ±5 % on the
speed; a turn in place settles at 92 % of 0.5 rad/s (the README's skid steering), hence 0.40 to
0.52 rad/s. "Standing still" is under 5 mm over at least 0.5 s of sim time.
"""

from __future__ import annotations

import math
import signal
import termios
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from bus_helpers import endpoint, free_port
from client_helpers import PtyClient, bus_args, client_command, pty_client, run_without_terminal
from server_helpers import REPO, TWIST, SimServer, module_server, reset_before_each, wait_until

from simbot.transform import yaw_of

WORLD = REPO / "tests" / "fixtures" / "teleop_boxes.sdf"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
SPEED, TURN_RATE, STOP_DISTANCE = 0.5, 0.5, 0.5
FRONT_LIDAR_X, BACK_LIDAR_X = 0.99, -0.95
BLOCK_FACE_X, BLOCK_LANE_Y, WALL_LANE_Y = 2.0, 4.0, -4.0
STILL_M = 0.005
READY = r"ahead (clear|\d+\.\d+ m)  behind (clear|\d+\.\d+ m)"

sim = module_server(str(WORLD), "realtime")
fresh_world = reset_before_each()

Sample = tuple[float, float, float, float]
"""(sim time, x, y, yaw) of the robot from one world state."""


def sample(sim: SimServer) -> Sample:
    state = sim.state()
    (x, y, _), quat = sim.pose(state=state)
    return state["sim_time"], x, y, yaw_of(quat)


def moved(a: Sample, b: Sample) -> float:
    return math.hypot(b[1] - a[1], b[2] - a[2])


def turned(a: Sample, b: Sample) -> float:
    """The change of heading from `a` to `b`, in (−π, π]."""
    return math.remainder(b[3] - a[3], math.tau)


def started(begin: Sample, now: Sample) -> bool:
    return moved(begin, now) > 0.03 or abs(turned(begin, now)) > 0.06


def place(sim: SimServer, x: float, y: float, yaw: float = 0.0) -> None:
    """Teleport the robot (standing, 0.1 m up: it settles on its tyres in a few ms)."""
    orientation = {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}
    reply = sim.call(
        "set_pose", {"name": "flexley_tug", "position": {"x": x, "y": y, "z": 0.1}, "orientation": orientation}
    )
    assert reply.get("ok") is True, f"set_pose refused: {reply}"


def after_sim_seconds(sim: SimServer, start: Sample, seconds: float) -> Sample:
    """The first sample at least `seconds` of sim time after `start` (waiting at most 10× as long on the wall clock)."""
    deadline = time.monotonic() + 10 * seconds + 5.0
    while (now := sample(sim))[0] - start[0] < seconds:
        assert time.monotonic() < deadline, f"sim time stalled at {now[0]:.3f} s"
        time.sleep(0.05)
    return now


def steady_motion(sim: SimServer, seconds: float = 1.0) -> tuple[Sample, Sample]:
    """Two samples `seconds` of sim time apart, once the robot is moving (after its first 0.2 s)."""
    begin = sample(sim)
    wait_until(lambda: started(begin, sample(sim)), timeout=10.0, what="the robot to move")
    start = after_sim_seconds(sim, sample(sim), 0.2)
    return start, after_sim_seconds(sim, start, seconds)


def assert_still(sim: SimServer, what: str) -> Sample:
    """The robot does not move over 0.5 s of sim time; the last sample."""
    start = sample(sim)
    end = after_sim_seconds(sim, start, 0.5)
    assert moved(start, end) < STILL_M and abs(turned(start, end)) < 0.01, (
        f"{what}: the robot moved {moved(start, end):.4f} m"
    )
    return end


def at_rest(sim: SimServer) -> Sample:
    """Waits until the robot stands still (it brakes within a few cm); the sample then."""
    previous = sample(sim)
    for _ in range(50):
        now = after_sim_seconds(sim, previous, 0.2)
        if moved(previous, now) < 0.002:
            return now
        previous = now
    raise AssertionError(f"the robot did not come to rest within 10 s of sim time (at {now[1]:.3f}, {now[2]:.3f})")


@contextmanager
def teleop(sim: SimServer) -> Iterator[PtyClient]:
    """simbot-teleop in a pty, once its status line shows both lidars' paths."""
    with pty_client(client_command("teleop", *bus_args(sim))) as client:
        client.wait_for(READY, timeout=20.0)
        yield client


def test_drive_stop_turn_and_quit_restoring_the_terminal(sim: SimServer) -> None:
    commands = sim.subscribe("cmd_vel", TWIST)
    with pty_client(client_command("teleop", *bus_args(sim))) as client:
        before = client.initial
        client.wait_for(READY, timeout=20.0)
        assert not client.attributes()[3] & termios.ICANON, "the client did not put the terminal in cbreak mode"
        screen = client.screen()
        assert "w forward" in screen and "q quit" in screen, "the keys are not shown"

        client.type("w")
        start, end = steady_motion(sim)
        speed = moved(start, end) / (end[0] - start[0])
        assert speed == pytest.approx(SPEED, rel=0.05), f"w drove at {speed:.4f} m/s"
        assert end[1] > start[1] and abs(end[2] - start[2]) < 0.01, "w did not drive straight forward"
        client.wait_for(r"v \+0\.50 m/s  w \+0\.00 rad/s")

        client.type("x")
        commands.wait_for(lambda ms: ms and ms[-1].linear.x == 0.0, what="a stop on cmd_vel")
        at_rest(sim)
        assert_still(sim, "after x")

        client.type("a")
        turn_start, turn_end = steady_motion(sim)
        rate = turned(turn_start, turn_end) / (turn_end[0] - turn_start[0])
        assert 0.8 * TURN_RATE <= rate <= 1.04 * TURN_RATE, f"a turned at {rate:.4f} rad/s (left is +z, REP-103)"
        assert moved(turn_start, turn_end) < 0.05, "a did not turn in place"

        client.type("w")
        commands.wait_for(lambda ms: ms and ms[-1].linear.x == SPEED, what="forward on cmd_vel")
        client.type("q")
        assert client.wait_exit() == 0
        assert client.attributes() == before, "the terminal's attributes were not restored"
        last = commands.wait_for(lambda ms: ms and ms[-1].linear.x == 0.0, what="the zero command at exit")[-1]
        assert (last.linear.x, last.linear.y, last.angular.z) == (0.0, 0.0, 0.0)
        at_rest(sim)
    print(f"\nmeasured teleop: w {speed:.4f} m/s, a {rate:.4f} rad/s (sim time)")


def test_obstacle_in_the_path_blocks_driving_towards_it_not_turning(sim: SimServer) -> None:
    place(sim, BLOCK_FACE_X - 0.4 - FRONT_LIDAR_X, BLOCK_LANE_Y)  # front lidar 0.4 m from the box
    commands = sim.subscribe("cmd_vel", TWIST)
    with teleop(sim) as client:
        client.wait_for(r"ahead 0\.(39|40|41) m")
        mark = client.mark()
        client.type("w")
        client.wait_for(r"BLOCKED forward", since=mark)
        # three more ticks of its 10 Hz commands: the refusal is logged once, not at every tick
        commands.wait_count(len(commands) + 3, what="three more ticks of teleop's cmd_vel")
        assert_still(sim, "w with a box 0.4 m ahead")
        assert client.screen()[mark:].count("forward blocked") == 1, "the block was not logged exactly once"

        turn_from = sample(sim)
        client.type("a")
        turn_to = after_sim_seconds(sim, turn_from, 0.8)
        assert turned(turn_from, turn_to) > 0.2, (
            f"turning in place was refused: yaw {turned(turn_from, turn_to):+.3f} rad"
        )
        client.type("x")
        at_rest(sim)

        place(sim, BLOCK_FACE_X - 0.4 + BACK_LIDAR_X, BLOCK_LANE_Y, math.pi)  # back lidar 0.4 m from the box
        client.wait_for(r"behind 0\.(39|40|41) m", since=client.mark())
        mark = client.mark()
        client.type("s")
        client.wait_for(r"BLOCKED backward", since=mark)
        assert_still(sim, "s with a box 0.4 m behind")
        client.type("x")

        place(sim, BLOCK_FACE_X - 1.0 - FRONT_LIDAR_X, BLOCK_LANE_Y)  # 1.0 m to go: drives 0.5 m, then stops
        client.wait_for(r"ahead (0\.99|1\.00|1\.01) m", since=client.mark())
        mark = client.mark()
        client.type("w")
        client.wait_for(r"BLOCKED forward", since=mark)
        rest = at_rest(sim)
        gap = BLOCK_FACE_X - (rest[1] + FRONT_LIDAR_X * math.cos(rest[3]))
        assert 0.25 < gap < STOP_DISTANCE, f"driving at the box, the front lidar stopped {gap:.3f} m from it"
        assert_still(sim, "w, stopped at the box")
    print(f"\nmeasured teleop: driving at a box, stopped with the front lidar {gap:.3f} m from it")


def test_wall_beside_the_path_does_not_stop_it(sim: SimServer) -> None:
    place(sim, 0.0, WALL_LANE_Y)
    scans = sim.subscribe("lidar_front", LASER_SCAN)
    wait_until(lambda: len(scans) >= 2, timeout=10.0, what="front scans")
    nearest = min(r for r in scans.messages()[-1].ranges if math.isfinite(r))
    assert nearest < STOP_DISTANCE, (
        f"the wall should be in the lidar's view within {STOP_DISTANCE} m, nearest return {nearest:.3f} m"
    )
    with teleop(sim) as client:
        client.wait_for(r"ahead clear")
        mark = client.mark()
        client.type("w")
        start, end = steady_motion(sim)
        speed = moved(start, end) / (end[0] - start[0])
        assert speed == pytest.approx(SPEED, rel=0.05), f"beside the wall, w drove at {speed:.4f} m/s"
        assert "BLOCKED" not in client.screen()[mark:]
        client.type("x")
    print(f"\nmeasured teleop: wall {nearest:.3f} m from the front lidar beside the path, drove at {speed:.4f} m/s")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_ends_it_with_a_stop_and_the_terminal_restored(sim: SimServer, sig: signal.Signals) -> None:
    commands = sim.subscribe("cmd_vel", TWIST)
    with pty_client(client_command("teleop", *bus_args(sim))) as client:
        before = client.initial
        client.wait_for(READY, timeout=20.0)
        client.type("w")
        commands.wait_for(lambda ms: ms and ms[-1].linear.x == SPEED, what="forward on cmd_vel")
        client.process.send_signal(sig)
        assert client.wait_exit() == 0
        assert client.attributes() == before, f"the terminal's attributes were not restored after {sig.name}"
        commands.wait_for(lambda ms: ms and ms[-1].linear.x == 0.0, what=f"the zero command after {sig.name}")


@pytest.mark.parametrize(
    ("args", "expected"),
    [((), "standard input is not a terminal"), (("--speed", "-1"), "--speed"), (("--margin", "nan"), "--margin")],
    ids=["not-a-terminal", "negative-speed", "nan-margin"],
)
def test_a_mistake_is_one_line_and_exit_2(sim: SimServer, args: tuple[str, ...], expected: str) -> None:
    done = run_without_terminal("teleop", *bus_args(sim), *args)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and expected in done.stderr.strip().splitlines()[-1], done.stderr


def test_without_a_terminal_it_says_so_before_looking_for_a_server() -> None:
    """No terminal and no server: the one line is about the terminal (checked before the bus opens)."""
    done = run_without_terminal("teleop", "--connect", endpoint(free_port()), "--connect-timeout", "5")
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "not a terminal" in done.stderr, done.stderr
