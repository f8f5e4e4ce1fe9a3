"""simbot-dock in a pseudo-terminal, docking the trolley of the warehouse on a real server in real time.

The robot is spawned under the trolley: at (1, 0), 0.2 m beside the trolley's centre (1, 0.2),
as tests/test_server_docking.py leaves it after driving in from (−2.5, 0). Its 0.5 m-wide,
0.3 m-high chassis passes between the legs (±0.65 from the trolley's centre) under the deck
(0.65 m up), so the trolley does not move when the robot appears there (checked: under 1 cm).

Attached, the trolley is fixed to the chassis and moves exactly as the robot does (the server's
docking test: within 2 cm over 2 m); detached, the robot slides out and the trolley stays (its
feet drag on the floor: under 3 cm). Distances are measured in sim time from the world state,
since the real-time factor may drop below 1 on a loaded machine.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager
from typing import Any

import pytest
from client_helpers import PtyClient, bus_args, client_command, pty_client, run_without_terminal
from server_helpers import (
    STRING,
    Collector,
    SimServer,
    planar_distance,
    reset_before_each,
    running_server,
    wait_until,
)

SPAWN_UNDER_TROLLEY = ("--spawn", "1.0", "0.0", "0.1", "0")
TROLLEY_XY = (1.0, 0.2)

fresh_world = reset_before_each()


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Iterator[SimServer]:
    with running_server("warehouse", "realtime", extra=SPAWN_UNDER_TROLLEY) as server:
        yield server


def dock(sim: SimServer, *args: str) -> AbstractContextManager[PtyClient]:
    return pty_client(client_command("dock", *bus_args(sim), *args))


def joint_states(sim: SimServer) -> Collector[Any]:
    """The joint's state as it changes, starting with the latched current one."""
    collector = sim.subscribe("detachable_joint/state", STRING, latched=True)
    collector.wait_count(1, what="the latched detachable_joint/state")
    return collector


def states(collector: Collector[Any]) -> list[str]:
    return [m.data for m in collector.messages()]


def attaches(sim: SimServer) -> int:
    """The attach commands the server has received."""
    return int(sim.state()["received"][sim.key("attach")])


def refused(sim: SimServer, client: PtyClient, collector: Collector[Any]) -> str:
    """Types t, waits for the warning, and makes sure nothing was attached: none reaches the server over five
    more check periods of sim time, by the end of which a second t is refused as well (the client's loop is
    past them)."""
    before = attaches(sim)
    mark = client.mark()
    client.type("t")
    warning = client.wait_for(r"not attaching: [^\n]*", since=mark).group(0)
    start = sim_time(sim)
    wait_until(lambda: sim_time(sim) - start >= 1.0, 20.0, "five check periods of sim time", poll=0.05)
    mark = client.mark()
    client.type("t")
    client.wait_for(r"not attaching: ", since=mark)
    assert attaches(sim) == before, "t while far sent an attach command"
    assert states(collector) == ["detached"], f"t while far changed the joint: {states(collector)}"
    return warning


def sim_time(sim: SimServer) -> float:
    return float(sim.state()["sim_time"])


def drive_for(sim: SimServer, speed: float, seconds: float) -> None:
    """Drive at `speed` for `seconds` of sim time, stop, and wait until the robot stands."""
    start = sim_time(sim)
    sim.drive(speed)
    wait_until(
        lambda: sim_time(sim) - start >= seconds, timeout=10 * seconds + 5.0, what=f"{seconds} s of sim time", poll=0.05
    )
    sim.drive(0.0)
    before = sim.pose()[0]
    for _ in range(50):
        time.sleep(0.2)
        now = sim.pose()[0]
        if planar_distance(before, now) < 0.002:
            return
        before = now
    raise AssertionError("the robot did not come to rest within 10 s of stopping it")


def test_without_a_pose_the_trolley_is_unknown_and_not_attached(sim: SimServer) -> None:
    collector = joint_states(sim)
    with dock(sim, "--trolley", "ghost") as client:
        client.wait_for(r"joint detached")
        client.wait_for(r"trolley far/unknown \(no recent pose of the trolley\)")
        warning = refused(sim, client, collector)
        assert "far/unknown" in warning


def test_far_from_the_trolley_t_warns_and_sends_nothing(sim: SimServer) -> None:
    sim.call("set_pose", {"name": "flexley_tug", "position": {"x": -2.5, "y": 0.0, "z": 0.1}})
    collector = joint_states(sim)
    with dock(sim) as client:
        before = client.initial
        client.wait_for(r"trolley far \(3\.5\d m apart\)")
        refused(sim, client, collector)
        client.type("q")
        assert client.wait_exit() == 0
        assert client.attributes() == before, "q did not restore the terminal's attributes"


def test_yaw_tolerance_refuses_a_skewed_robot(sim: SimServer) -> None:
    """Centred under the trolley but turned 0.15 rad: near by distance, far by a 0.1 rad heading tolerance."""
    yaw = 0.15
    orientation = {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}
    sim.call(
        "set_pose",
        {
            "name": "flexley_tug",
            "position": {"x": TROLLEY_XY[0], "y": TROLLEY_XY[1], "z": 0.1},
            "orientation": orientation,
        },
    )
    collector = joint_states(sim)
    with dock(sim, "--yaw-tolerance", "0.1") as client:
        client.wait_for(r"trolley far \(0\.0\d m apart, headings 0\.1[45] rad apart\)")
        refused(sim, client, collector)


def test_under_the_trolley_attach_pull_detach(sim: SimServer) -> None:
    (trolley0, _), (robot0, _) = sim.pose("trolley"), sim.pose()
    assert planar_distance(trolley0, TROLLEY_XY) < 0.01, (
        f"the robot spawned under the trolley pushed it to {trolley0[:2]}"
    )
    collector = joint_states(sim)
    with dock(sim) as client:
        client.wait_for(r"trolley near \(0\.20 m apart\)")
        mark = client.mark()
        client.type("t")
        client.wait_for(r"checking 1/3[\s\S]*checking 2/3[\s\S]*attach sent: 3 checks near", since=mark)
        collector.wait_for(lambda ms: ms[-1].data == "attached", what="'attached'")
        client.wait_for(r"joint attached\b")
        mark = client.mark()
        client.type("t")
        client.wait_for(r"already attached", since=mark)

        drive_for(sim, 0.5, 2.0)
        (trolley1, _), (robot1, _) = sim.pose("trolley"), sim.pose()
        pulled, drove = planar_distance(trolley0, trolley1), planar_distance(robot0, robot1)
        assert drove > 0.9, f"the robot drove only {drove:.3f} m in 2 s at 0.5 m/s"
        assert abs(pulled - drove) < 0.02, f"attached, the trolley moved {pulled:.4f} m, the robot {drove:.4f} m"

        mark = client.mark()
        client.type("r")
        collector.wait_for(lambda ms: ms[-1].data == "detached", what="'detached'")
        client.wait_for(r"joint detached", since=mark)

        drive_for(sim, 0.5, 2.0)
        (trolley2, _), (robot2, _) = sim.pose("trolley"), sim.pose()
        left, stayed = planar_distance(robot1, robot2), planar_distance(trolley1, trolley2)
        assert left > 0.9 and stayed < 0.03, (
            f"detached, the robot drove {left:.3f} m and the trolley moved {stayed:.4f} m"
        )
        client.wait_for(r"trolley far \(\d+\.\d+ m apart\)", since=mark)
    assert states(collector) == ["detached", "attached", "detached"]
    print(
        f"\nmeasured docking: attached, trolley {pulled:.4f} m with the robot's {drove:.4f} m; detached, robot {left:.4f} m, trolley {stayed:.4f} m"
    )


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        ((), "standard input is not a terminal"),
        (("--distance", "0"), "--distance"),
        (("--yaw-tolerance", "inf"), "--yaw-tolerance"),
    ],
    ids=["not-a-terminal", "zero-distance", "infinite-yaw-tolerance"],
)
def test_a_mistake_is_one_line_and_exit_2(sim: SimServer, args: tuple[str, ...], expected: str) -> None:
    done = run_without_terminal("dock", *bus_args(sim), *args)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and expected in done.stderr.strip().splitlines()[-1], done.stderr


def test_checks_count_sim_time_not_wall_time() -> None:
    """In lockstep the world stands still between steps: the checks wait for sim time, however long in wall time."""
    with running_server("warehouse", "lockstep", extra=SPAWN_UNDER_TROLLEY) as sim:
        collector = joint_states(sim)
        with dock(sim) as client:
            wait_until(
                lambda: sim.step(20) and all(text in client.screen() for text in ("trolley near", "joint detached")),
                20.0,
                "near once the poses and the clock come, and the joint's state",
                poll=0.05,
            )
            mark = client.mark()
            client.type("t")
            client.wait_for(r"checking 1/3", since=mark)
            time.sleep(1.0)  # the stimulus, not a wait: five check periods of wall time, none of sim time
            client.type("r")  # the marker: the client's loop went on through that second (r ends the attempt)
            answer = client.wait_for(r"already detached", since=mark)
            assert "checking 2/3" not in client.screen()[mark : mark + answer.start()]
            assert states(collector) == ["detached"]
            mark = client.mark()
            client.type("t")
            client.wait_for(r"checking 1/3", since=mark)
            sim.step(250)  # a check period and a clock tick or two
            client.wait_for(r"checking 2/3", since=mark)
            sim.step(250)
            client.wait_for(r"attach sent: 3 checks near", since=mark)
            # the command is applied at the next step, which in lockstep comes only when asked for
            wait_until(
                lambda: sim.step(10) and states(collector)[-1:] == ["attached"], 10.0, "'attached' at the next steps"
            )
