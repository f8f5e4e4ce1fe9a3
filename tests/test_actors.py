"""Gazebo actors through the real server (tests/fixtures/actors.sdf, lockstep, no robot).

The walker's script (a 1 s delay, then y −4 → +4 in 8 s, looping) is followed as gz-sim follows
it: gz-math's Hermite spline, whose two-waypoint segment at tension 0 is p0 + d·(1.5 s² − s³ + 0.5 s)
of the time fraction s, where linear interpolation is at s = 0, ½ and 1 and eased between. The
sensors on the post at the origin see its proxy (a capsule 0.25 m in radius about the actor's z
axis at x 3): the lidar's middle ray reads its near face, 2.75 m, as it crosses, and the wall,
6.0 m, once it has passed; the camera sees its orange where the pinhole projection puts it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from server_helpers import SimServer, module_server, reset_before_each

from simbot.bus import messages
from simbot.transform import yaw_of

REPO = Path(__file__).resolve().parents[1]
WORLD = str(REPO / "tests" / "fixtures" / "actors.sdf")
DELAY, DURATION, START_Y, END_Y = 1.0, 8.0, -4.0, 4.0
WALKER_X, WALKER_Z = 3.0, 1.0
PROXY_RADIUS, WALL_X = 0.25, 6.0
STEPS_PER_S = 1000
CM = 0.01


sim = module_server(WORLD, extra=("--robot", "none"))
"""The world alone, in lockstep."""
fresh_world = reset_before_each()


def _gazebo_y(time: float) -> float:
    """Where gz-sim's spline puts the walker along y at `time` seconds of sim time (looping)."""
    s = ((time - DELAY) % DURATION if time - DELAY > DURATION else max(time - DELAY, 0.0)) / DURATION
    return START_Y + (END_Y - START_Y) * (1.5 * s * s - s**3 + 0.5 * s)


def _at(sim: SimServer, time: float) -> dict[str, float]:
    """Steps the world (from where it is) to `time` and returns the walker's ground truth."""
    now = sim.state()["sim_time"]
    steps = round((time - now) * STEPS_PER_S)
    if steps:
        sim.step(steps)
    (x, y, z), quat = sim.pose("walker")
    return {"x": x, "y": y, "z": z, "yaw": yaw_of(quat)}


def test_the_walker_is_where_linear_interpolation_puts_it_at_the_start_middle_and_end(sim: SimServer) -> None:
    for time, expected in ((DELAY, START_Y), (DELAY + DURATION / 2, 0.0), (DELAY + DURATION, END_Y)):
        pose = _at(sim, time)
        linear = START_Y + (END_Y - START_Y) * (time - DELAY) / DURATION
        assert expected == pytest.approx(linear)
        assert abs(pose["y"] - linear) <= CM, f"at {time} s the walker is at y {pose['y']:.4f}, not {linear}"
        assert abs(pose["x"] - WALKER_X) <= CM and abs(pose["z"] - WALKER_Z) <= CM
        assert pose["yaw"] == pytest.approx(1.5708, abs=1e-4)


def test_between_waypoints_it_eases_as_gazebos_spline_does(sim: SimServer) -> None:
    """A quarter of the way in time it has gone 20.3 % of the way (linear: 25 %), as gz-math's Hermite gives."""
    pose = _at(sim, DELAY + DURATION / 4)
    assert abs(pose["y"] - _gazebo_y(DELAY + DURATION / 4)) <= CM
    assert abs(pose["y"] - (START_Y + 2.0)) > 0.3, "the walker moved linearly, not as Gazebo moves it"


def test_it_waits_for_its_delay_then_loops(sim: SimServer) -> None:
    before = _at(sim, DELAY / 2)
    assert abs(before["y"] - START_Y) <= CM, f"the walker moved before its delay: y {before['y']}"
    after_loop = _at(sim, DELAY + DURATION + 1.0)
    assert abs(after_loop["y"] - _gazebo_y(DELAY + DURATION + 1.0)) <= CM
    assert after_loop["y"] < START_Y + 1.0, "after its last waypoint the walker did not start over"


def test_the_turner_turns_in_place_and_stays_turned(sim: SimServer) -> None:
    """No loop: its yaw goes 0 → π/2 in 2 s (squad between two rotations: π/4 half way) and stays."""
    (x, y, _), quat = sim.pose("turner")
    assert (x, y) == pytest.approx((-3.0, 0.0), abs=1e-6) and abs(yaw_of(quat)) < 1e-6
    _at(sim, 1.0)
    assert yaw_of(sim.pose("turner")[1]) == pytest.approx(math.pi / 4, abs=1e-4)
    _at(sim, 5.0)
    (x, y, _), quat = sim.pose("turner")
    assert yaw_of(quat) == pytest.approx(math.pi / 2, abs=1e-4) and (x, y) == pytest.approx((-3.0, 0.0), abs=1e-6)


def _message_at(sim: SimServer, topic: str, typename: str, time: float) -> Any:
    """The message of `topic` stamped `time`: subscribed and primed first (a camera starts its render
    workers on its first subscriber), then stepped to `time`."""
    collector = sim.subscribe(topic, typename)
    sim.prime(collector, chunk=20, timeout=120.0)
    assert sim.state()["sim_time"] < time, "priming took the world past the time asked for"
    _at(sim, time)
    return collector.wait_stamp(round(time * 1e9), timeout=120.0, what=f"{topic} at {time} s")


def _scan_at(sim: SimServer, time: float) -> float:
    """The lidar's middle ray at `time`."""
    scan = _message_at(sim, "post/scan", "sensor_msgs/msg/LaserScan", time)
    return float(scan.ranges[len(scan.ranges) // 2])


def test_the_lidar_reads_the_proxys_near_face_as_it_crosses_and_the_wall_once_it_has_passed(sim: SimServer) -> None:
    crossing = _scan_at(sim, DELAY + DURATION / 2)
    assert abs(crossing - (WALKER_X - PROXY_RADIUS)) <= CM, f"the lidar read {crossing} m at the crossing"
    passed = _scan_at(sim, DELAY + DURATION)
    assert abs(passed - WALL_X) <= CM, f"the lidar read {passed} m once the walker had passed"


def _orange(image: np.ndarray) -> np.ndarray:
    """The proxy's high-visibility orange, lit or in shade: red twice green, green far over blue."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return (r > 60) & (r > 1.6 * g) & (g > 2 * b) & (g > 15)


def _image_at(sim: SimServer, time: float) -> np.ndarray:
    return messages.image_pixels(_message_at(sim, "post/image", "sensor_msgs/msg/Image", time))


def test_the_camera_sees_the_walker_where_the_projection_puts_it(sim: SimServer) -> None:
    """At the crossing the capsule (its axis 3 m away, 0.25 m in radius) stands in the middle of the
    image, 2·fx·tan(asin(0.25 / 3)) = 23.2 px wide (fx = 80 / tan 30° = 138.6 px; the edges of its
    silhouette are tangents from the camera); once it has passed, no orange is left."""
    crossing = _orange(_image_at(sim, DELAY + DURATION / 2))
    columns = np.flatnonzero(crossing[60])
    assert len(columns), "the camera shows no orange in its middle row at the crossing"
    fx = 80 / math.tan(1.0472 / 2)
    expected = 2 * fx * math.tan(math.asin(PROXY_RADIUS / WALKER_X))
    assert abs(len(columns) - expected) <= 3, (
        f"the walker is {len(columns)} px wide, the projection says {expected:.1f}"
    )
    assert abs((columns[0] + columns[-1]) / 2 - 79.5) <= 1.5, "the walker is not in the middle of the image"
    assert crossing[:, 60:100].any(axis=1).sum() > 60, "the walker does not stand from the floor up past the camera"
    passed = _orange(_image_at(sim, DELAY + DURATION))
    assert int(passed.sum()) == 0, f"{int(passed.sum())} orange pixels once the walker has passed"


def test_ground_truth_on_model_pose_is_where_the_script_puts_it(sim: SimServer) -> None:
    time = DELAY + DURATION / 4
    pose = _message_at(sim, "model/walker/pose", "geometry_msgs/msg/PoseStamped", time)
    assert pose.header.frame_id == "world"
    assert abs(pose.pose.position.y - _gazebo_y(time)) <= CM and abs(pose.pose.position.x - WALKER_X) <= CM


def test_set_pose_moves_the_trajectorys_origin_and_reset_brings_it_back(sim: SimServer) -> None:
    """As Gazebo's set_pose sets an actor's Pose component: the script runs on from the new frame."""
    _at(sim, DELAY)
    reply = sim.call("set_pose", {"name": "walker", "position": {"x": 1.0, "y": 2.0, "z": 1.0}})
    assert reply["ok"], reply
    moved = _at(sim, DELAY + DURATION / 2)
    assert abs(moved["x"] - 1.0) <= CM and abs(moved["y"] - 2.0) <= CM, moved
    assert moved["yaw"] == pytest.approx(1.5708, abs=1e-4)
    assert sim.control({"reset": {"all": True}})["ok"]
    (x, y, z), _ = sim.pose("walker")
    assert (x, y, z) == pytest.approx((WALKER_X, START_Y, WALKER_Z), abs=CM)
    again = _at(sim, DELAY + DURATION / 2)
    assert abs(again["x"] - WALKER_X) <= CM and abs(again["y"]) <= CM, again
