"""Gazebo's systems that move things, through the real server (tests/fixtures/followers.sdf, lockstep).

FollowActor: the follower walks at its `velocity` (1 m/s) straight at red_box until it is
`min_distance` (1 m) from it, facing it; when the box is put elsewhere it turns and follows, and a
box put beyond `max_distance` (8 m) is not followed. TrajectoryFollower: the cart, pushed by its
force and turned by its torque, comes within `range_tolerance` of each waypoint in turn, and
loops.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from server_helpers import SimServer, module_server, reset_before_each

from simbot.transform import yaw_of

REPO = Path(__file__).resolve().parents[1]
WORLD = str(REPO / "tests" / "fixtures" / "followers.sdf")
CM = 0.01
WAYPOINTS = ((4.0, -5.0), (4.0, -8.0), (0.0, -5.0))
RANGE_TOLERANCE = 0.5


sim = module_server(WORLD, extra=("--robot", "none"))
"""The world alone, in lockstep."""
fresh_world = reset_before_each()


def _planar(sim: SimServer, model: str) -> tuple[float, float, float]:
    (x, y, _), quat = sim.pose(model)
    return x, y, yaw_of(quat)


def test_the_follower_walks_at_its_velocity_and_stops_at_its_min_distance(sim: SimServer) -> None:
    sim.step(2000)
    x, y, yaw = _planar(sim, "follower")
    assert (x, y) == pytest.approx((2.0, 0.0), abs=CM) and yaw == pytest.approx(0.0, abs=1e-4)
    assert sim.pose("follower")[0][2] == pytest.approx(1.0, abs=1e-6), "the follower left its height"
    sim.step(3000)
    x, y, _ = _planar(sim, "follower")
    assert (x, y) == pytest.approx((4.0, 0.0), abs=CM), "the follower did not stop 1 m from the box"


def test_the_follower_turns_after_a_moved_target_and_ignores_one_out_of_range(sim: SimServer) -> None:
    sim.step(5000)
    assert sim.call("set_pose", {"name": "red_box", "position": {"x": 0.0, "y": 5.0, "z": 0.5}})["ok"]
    sim.step(2000)
    x, y, yaw = _planar(sim, "follower")
    heading = math.atan2(5.0, -4.0)
    assert (x, y) == pytest.approx((4.0 + 2.0 * math.cos(heading), 2.0 * math.sin(heading)), abs=0.02)
    assert yaw == pytest.approx(heading, abs=1e-3)
    assert sim.call("set_pose", {"name": "red_box", "position": {"x": 30.0, "y": 0.0, "z": 0.5}})["ok"]
    sim.step(1000)
    assert _planar(sim, "follower")[:2] == pytest.approx((x, y), abs=1e-6), "the follower followed a box 27 m away"


def test_the_trajectory_follower_reaches_each_waypoint_in_turn_and_loops(sim: SimServer) -> None:
    """Ground truth at 50 Hz for 30 s: the cart's nearest approach to each waypoint, in order, is
    within the range tolerance (plus the 6 cm a 3 m/s cart covers between two samples)."""
    poses = sim.subscribe("model/cart/pose", "geometry_msgs/msg/PoseStamped")
    sim.prime(poses)
    for _ in range(30):
        sim.step(1000)
    track = [(m.pose.position.x, m.pose.position.y) for m in poses.wait_count(1400, timeout=60.0, what="cart poses")]
    order = [*WAYPOINTS, WAYPOINTS[0]]
    index = 0
    for goal in order:
        near = next((i for i in range(index, len(track)) if math.dist(track[i], goal) <= RANGE_TOLERANCE + 0.06), None)
        assert near is not None, f"the cart never came within {RANGE_TOLERANCE} m of {goal} after sample {index}"
        index = near + 1
