"""Docking in the warehouse on a real server: drive under the trolley, attach, pull it 2 m, detach, leave it.

The robot spawns at x −2.5 and the trolley stands at (1, 0.2): 3.5 m at 0.5 m/s is 7 s of sim
time to bring the robot's centre under the trolley's centre (its 1.4 m deck is 0.65 m up, its
legs at ±0.65, so the 0.3 m-high, 0.5 m-wide tug passes between them without touching). Attached,
the trolley is fixed to the chassis, so it moves exactly as the robot does: 2 m ± 0.1 for 4 s at
0.5 m/s (its feet have μ 0.05 on 5 kg: 2.5 N of drag against the wheels' ~900 N of traction).
Detached, the robot drives forward and slides out from under the deck: the trolley stays put.
"""

from __future__ import annotations

from typing import Any

import pytest
from server_helpers import (
    STRING,
    Collector,
    SimServer,
    module_server,
    planar_distance,
    reset_before_each,
    wrap,
)

from simbot.bus import messages
from simbot.transform import yaw_of

sim = module_server("warehouse")
fresh_world = reset_before_each()


def _late_joiner_sees(sim: SimServer, expected: str) -> None:
    """A new client node subscribing now (latched) gets the current state without any new change."""
    with sim.client() as late:
        seen: Collector[Any] = Collector()
        late.subscribe("detachable_joint/state", STRING, seen, latched=True)
        got = seen.wait_count(1, timeout=5.0, what="detachable_joint/state for a late joiner")
        assert got[0].data == expected, f"a late joiner got {got[0].data!r}, the joint is {expected!r}"


def _drive_then_stop(sim: SimServer, vx: float, steps: int, settle_steps: int) -> None:
    """Drive at `vx` for `steps` physics steps, then stop and let the robot come to rest for `settle_steps`."""
    sim.drive(vx)
    sim.step(steps)
    sim.drive(0.0)
    sim.step(settle_steps)


def test_dock_pull_and_leave_the_trolley(sim: SimServer) -> None:
    state = sim.subscribe("detachable_joint/state", STRING, latched=True)
    state.wait_count(1, what="the latched detachable_joint/state")
    assert state.messages()[0].data == "detached"
    sim.step(500)  # settle on the tyres
    (trolley0, _), (robot0, robot_quat0) = sim.pose("trolley"), sim.pose()

    # drive under: 3.5 m at 0.5 m/s
    _drive_then_stop(sim, 0.5, 7000, settle_steps=1000)
    (trolley1, _), (robot1, robot_quat1) = sim.pose("trolley"), sim.pose()
    assert robot1[0] == pytest.approx(trolley1[0], abs=0.15), (
        f"robot centre x {robot1[0]:.3f} is not under the trolley's {trolley1[0]:.3f}"
    )
    assert abs(robot1[1] - robot0[1]) < 0.05 and abs(wrap(yaw_of(robot_quat1) - yaw_of(robot_quat0))) < 0.05, (
        "the robot veered"
    )
    assert planar_distance(trolley0, trolley1) < 0.01, "the robot touched the trolley driving under it"

    sim.send("attach", messages.empty())
    sim.step(10)
    state.wait_for(lambda ms: [m.data for m in ms][-1:] == ["attached"], what="'attached' on detachable_joint/state")
    _late_joiner_sees(sim, "attached")

    # pull: 2 m at 0.5 m/s
    _drive_then_stop(sim, 0.5, 4000, settle_steps=1000)
    (trolley2, _), (robot2, _) = sim.pose("trolley"), sim.pose()
    pulled = planar_distance(trolley1, trolley2)
    robot_moved = planar_distance(robot1, robot2)
    assert pulled == pytest.approx(2.0, abs=0.1), (
        f"attached, the trolley moved {pulled:.4f} m while the robot drove 2 m"
    )
    assert abs(pulled - robot_moved) < 0.02, (
        f"the trolley moved {pulled:.4f} m, the robot {robot_moved:.4f} m: not rigidly attached"
    )
    assert trolley2[0] > trolley1[0]

    sim.send("detach", messages.empty())
    sim.step(10)
    state.wait_for(lambda ms: [m.data for m in ms][-1:] == ["detached"], what="'detached' on detachable_joint/state")
    _late_joiner_sees(sim, "detached")

    # drive away forwards 1 m: the robot slides out from under the deck
    _drive_then_stop(sim, 0.5, 2000, settle_steps=500)
    (trolley3, _), (robot3, _) = sim.pose("trolley"), sim.pose()
    left = planar_distance(robot2, robot3)
    stayed = planar_distance(trolley2, trolley3)
    assert left == pytest.approx(1.0, rel=0.05), f"the robot drove {left:.4f} m away"
    assert stayed < 0.05, f"detached, the trolley moved {stayed:.4f} m with the robot"

    assert [m.data for m in state.messages()] == ["detached", "attached", "detached"]
    print(
        f"\nmeasured docking: robot under the trolley at dx {robot1[0] - trolley1[0]:+.4f} m; attached, trolley moved "
        f"{pulled:.4f} m (robot {robot_moved:.4f} m); detached, robot moved {left:.4f} m and the trolley {stayed:.6f} m"
    )


def test_detach_when_detached_and_attach_twice_change_nothing(sim: SimServer) -> None:
    """Only changes are published: a second attach, or a detach while detached, says nothing new."""
    state = sim.subscribe("detachable_joint/state", STRING, latched=True)
    state.wait_count(1, what="the latched detachable_joint/state")
    sim.send("detach", messages.empty())
    sim.step(10)
    sim.send("attach", messages.empty())
    sim.step(10)
    sim.send("attach", messages.empty())
    sim.step(10)
    state.wait_for(lambda ms: len(ms) >= 2, what="'attached'")
    sim.step(10)
    assert [m.data for m in state.messages()] == ["detached", "attached"]
    # reset detaches, and says so
    sim.reset()
    state.wait_for(lambda ms: len(ms) >= 3, what="'detached' after the reset")
    assert [m.data for m in state.messages()] == ["detached", "attached", "detached"]
    _late_joiner_sees(sim, "detached")
