"""The teleop's obstacle stop halts the tug for a person stepping into its path (a real pty, a real
server in real time: tests/fixtures/teleop_person.sdf).

simbot-teleop drives the tug along the lane at 0.5 m/s; once it is under way, the person beside the
lane steps into it (world control's set_pose puts the actor's frame there), more than 1 m ahead of
the front lidar. The lidars see the actor's proxy as any collision: the teleop refuses to drive on
(`BLOCKED forward`) and the tug stops short of the person, the front lidar between 0.25 m (its
braking from 0.5 m/s at the lidars' 5 Hz) and the 0.5 m stop distance from the proxy's near face.
"""

from __future__ import annotations

import math

from server_helpers import REPO, SimServer, module_server, reset_before_each, wait_until
from test_client_teleop import FRONT_LIDAR_X, STOP_DISTANCE, after_sim_seconds, at_rest, sample, teleop

WORLD = REPO / "tests" / "fixtures" / "teleop_person.sdf"
PERSON_X, PROXY_RADIUS = 1.2, 0.25

sim = module_server(str(WORLD), "realtime")
fresh_world = reset_before_each()


def test_the_tug_stops_for_a_person_stepping_into_its_path(sim: SimServer) -> None:
    with teleop(sim) as client:
        client.wait_for(r"ahead clear")
        mark = client.mark()
        client.type("w")
        start = sample(sim)
        wait_until(lambda: sample(sim)[1] > start[1] + 0.2, timeout=20.0, what="the tug to drive")
        lidar_x = sample(sim)[1] + FRONT_LIDAR_X
        assert PERSON_X - PROXY_RADIUS - lidar_x > 1.0, (
            f"the tug was already at x {lidar_x:.2f} when the person stepped in"
        )
        reply = sim.call("set_pose", {"name": "person", "position": {"x": PERSON_X, "y": 0.0, "z": 1.0}})
        assert reply["ok"], reply
        client.wait_for(r"BLOCKED forward", since=mark, timeout=30.0)
        rest = at_rest(sim)
        gap = PERSON_X - PROXY_RADIUS - (rest[1] + FRONT_LIDAR_X * math.cos(rest[3]))
        assert 0.25 < gap < STOP_DISTANCE, f"the front lidar stopped {gap:.3f} m from the person"
        later = after_sim_seconds(sim, rest, 0.5)
        assert math.hypot(later[1] - rest[1], later[2] - rest[2]) < 0.005, "the tug crept on towards the person"
        client.type("x")
    print(f"\nmeasured: the tug stopped with its front lidar {gap:.3f} m from a person who stepped into its path")
