"""What every drive does with its command, DiffDrive, AckermannSteering and MecanumDrive alike
(simbot.sim.kit.command_pipeline): ramped at the acceleration limit and then clamped to the velocity
limit each step, held while no command comes, and back to zero at a reset.

Each drive runs in a kinematic world (simbot.sim.physics.kinematic_world), where the base moves
by exactly the twist its drive commands, x += v·dt each 5 ms step: what the command pipeline gave
is then the truth's to rounding. PyBullet keeps a base's position in float32, so each step rounds
it by up to 2^-24 of itself: 200 steps of at most 0.33 m, 4e-6 m at the most. A step of the ramp
misplaced moves the base by a·dt² = 2.5e-5 m.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest
from bus_helpers import wait_until
from test_sim_drive_systems import BOT, Rig, _car, _hinge, _inertial, _mecanum, _robot, _wheel, lockstep

from simbot.bus import encode, messages
from simbot.sim.loop.bus_view import Doorbell
from simbot.sim.physics.kinematic_world import KINEMATIC_STEP_S

MAX_SPEED, MAX_ACCELERATION = 0.4, 1.0
LIMITS = f"<max_velocity>{MAX_SPEED}</max_velocity><max_acceleration>{MAX_ACCELERATION}</max_acceleration>"
"""The spelling all three take: AckermannSteering and MecanumDrive bound every component by it,
DiffDrive its linear speed (the older names of `max_linear_velocity` and `_acceleration`)."""
ASKED = 1.0
"""m/s forward: beyond the limit."""
EXACT = 5e-6
"""m: the float32 rounding of 200 steps (the module's docstring)."""


def _diff_drive() -> str:
    """Two wheels 0.5 m apart on a box; kinematically, nothing needs a castor."""
    wheels = "".join(
        _wheel(f"{side}_wheel", (0.0, y, 0.1), 0.1) + _hinge(f"{side}_axle", "chassis", f"{side}_wheel")
        for side, y in (("left", 0.25), ("right", -0.25))
    )
    return _robot(f"""<link name="chassis"><pose>0 0 0.15 0 0 0</pose>{_inertial(10.0, 0.1, 0.2, 0.3)}
        <collision name="c"><geometry><box><size>0.5 0.4 0.05</size></box></geometry></collision></link>
      {wheels}
      <plugin name="gz::sim::systems::DiffDrive" filename="gz-sim-diff-drive-system">
        <left_joint>left_axle</left_joint><right_joint>right_axle</right_joint>
        <wheel_separation>0.5</wheel_separation><wheel_radius>0.1</wheel_radius>
      </plugin>""")


DRIVES = {"DiffDrive": _diff_drive, "AckermannSteering": _car, "MecanumDrive": _mecanum}


def _limited(robot: str) -> str:
    return robot.replace("</plugin>", f"{LIMITS}</plugin>")


def _ramped(steps: int) -> float:
    """Metres the base goes in `steps` steps from rest: Σ min(k·a·dt, v_max)·dt."""
    dt = KINEMATIC_STEP_S
    return sum(min(k * MAX_ACCELERATION * dt, MAX_SPEED) * dt for k in range(1, steps + 1))


def _command(rig: Rig, speed: float) -> None:
    """Puts a forward twist on cmd_vel and waits until the drive's input holds it (again)."""
    topic = f"{BOT}/cmd_vel"
    (drive,) = (i for i in rig.server.bus.inputs if i.key == rig.node.key(topic))
    before = drive.received
    message = messages.twist((speed, 0.0, 0.0), (0.0, 0.0, 0.0))
    rig.node.session.put(rig.node.data_key(topic, message.__msgtype__), encode(message))
    wait_until(lambda: drive.received > before, 5.0, f"{topic} at its input")


def _steps(rig: Rig, count: int) -> None:
    for _ in range(count):
        rig.server.sim.step()


def _stamp_ns(message: Any) -> int:
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def _x(rig: Rig) -> float:
    return rig.pose()[0]


@pytest.mark.parametrize("robot", DRIVES.values(), ids=DRIVES.keys())
def test_a_command_beyond_the_limits_is_ramped_then_clamped(tmp_path: Path, robot: Any) -> None:
    """1 m/s asked of 0.4 m/s and 1 m/s²: the speed rises by a·dt a step, reaches 0.4 m/s after
    0.4 s (80 steps) and holds there while no other command comes: 0.0205 m after 40 steps, 0.321 m
    after 200. Straight ahead: no sideways motion, no turn."""
    with lockstep(tmp_path, _limited(robot()), kinematic=True) as rig:
        _command(rig, ASKED)
        _steps(rig, 40)
        ramping = _x(rig)
        _steps(rig, 160)
        x, y, yaw = rig.pose()
    assert ramping == pytest.approx(_ramped(40), abs=EXACT)
    assert x == pytest.approx(_ramped(200), abs=EXACT)
    assert (y, yaw) == pytest.approx((0.0, 0.0), abs=EXACT)


@pytest.mark.parametrize("robot", DRIVES.values(), ids=DRIVES.keys())
def test_a_reset_stands_the_drive_and_its_next_command_ramps_from_zero(tmp_path: Path, robot: Any) -> None:
    """At its limit and idle (its command holds), the world is reset: the drive stands where it was
    built for 0.5 s, its odometry at the origin; the same command again ramps from rest, as the
    first did, not from the speed it had before the reset."""
    with lockstep(tmp_path, _limited(robot()), kinematic=True) as rig:
        odometry = rig.collect(f"{BOT}/odometry", "nav_msgs/msg/Odometry")
        _command(rig, ASKED)
        _steps(rig, 200)
        wait_until(lambda: odometry and _stamp_ns(odometry[-1]) == 1_000_000_000, 5.0, "odometry at 1 s")
        rig.server.sim.reset()
        odometry.clear()
        _steps(rig, 100)
        standing = rig.pose()
        wait_until(lambda: odometry and _stamp_ns(odometry[-1]) == 500_000_000, 5.0, "odometry 0.5 s after the reset")
        odom = odometry[-1].pose.pose.position
        _command(rig, ASKED)
        _steps(rig, 40)
        again = _x(rig)
    assert standing == pytest.approx((0.0, 0.0, 0.0), abs=EXACT)
    assert (odom.x, odom.y) == pytest.approx((0.0, 0.0), abs=EXACT)
    assert again == pytest.approx(_ramped(40), abs=EXACT)


def test_the_doorbell_answers_each_system_once_in_the_order_they_joined_and_forgets_one_gone() -> None:
    """What a fleet's drives ring when a command comes (on the bus's threads, many at once): each
    answered once, in the order they joined whatever order they rang in; one gone is not answered."""
    bell = Doorbell()
    owners = [f"drive_{i}" for i in range(200)]
    for owner in owners:
        bell.join(owner)
    assert bell.answer() == owners, "each rung once at joining, for its first step"
    assert bell.answer() == []

    def ring(part: list[str]) -> None:
        for owner in reversed(part * 3):
            bell.ring(owner)

    threads = [threading.Thread(target=ring, args=(owners[i::4],)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    bell.leave("drive_7")
    bell.ring("drive_7")
    assert bell.answer() == [owner for owner in owners if owner != "drive_7"]
