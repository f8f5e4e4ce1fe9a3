"""The warehouse with its people (`simbot-server --add warehouse_people`, what `make run` starts).

One server in lockstep: the warehouse, the tug standing at its spawn, and
worlds/additions/warehouse_people.sdf added. Its three workers walk by the social-force model
(simbot.sim.systems.crowd) along the corners of their scripts. Each goes round its whole loop,
reaching every corner in order, the k-th within ROUND_MARGIN times the route's length up to it at
its desired speed (the script's mean speed) plus START_S; keeps at least its radius from the
racks, pillars, work cells and trolley (it walks their faces 0.8 m and more away, beyond the
obstacles' cutoff: nothing pushes it off its line, which stays within OFF_LINE_M); and the
crossing worker, whose first leg runs 0.95 m before the standing tug's front, passes it at ≥ 0.5 m
from its chassis. Driven at the crossing worker, the tug never has a worker nearer its chassis
than their radius. Each worker's ground truth on `model/<name>/pose` is where the world state has
it. The cart, pushed by its TrajectoryFollower from rest, reaches its first waypoint and heads on
for the second.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from server_helpers import POSE_STAMPED, REPO, SimServer, pose_of, running_server
from test_worlds import collision_boxes, planar_gap

from simbot.description import load_world
from simbot.description.actor_scripts import ActorModel
from simbot.description.crowd_params import Crowd
from simbot.sim.kit.social_force import Boxes
from simbot.sim.server import world_path

PEOPLE = REPO / "worlds" / "additions" / "warehouse_people.sdf"
CROWD = Crowd()
SAMPLE_STEPS = 100
"""Physics steps (1 ms) between two looks at the world state."""
ROUND_MARGIN = 1.15
"""A worker slows into each corner (its velocity turns within a few relaxation times), which the
script's mean speed, taken over its turns on the spot, more than makes up for."""
START_S = 3 * CROWD.relaxation_time
"""Seconds to take up the desired speed from rest."""
ROUND_S = 46.0
"""Seconds of sim time to watch: the longest bound, worker_north's 26 m at 0.71 m/s, and more."""
OFF_LINE_M = 0.35
"""Metres a worker alone may stray from the straight line between its corners: the corner it cuts
(its heading turns within τ at its speed, under 0.35 m) and the jitter."""
TUG_SPAWN = (-2.5, 0.0)
TUG_HALF = (1.05, 0.25)
"""The chassis collision box 2.1 × 0.5 m, centred on the model frame (SPEC.md)."""
STEP_TRAVEL = 0.5 * 0.001
"""Metres the tug driven at 0.5 m/s moves in one step, after the person was placed."""
CART_START, CART_FIRST, CART_SECOND = (5.8, -1.0), (5.8, 2.5), (8.5, 2.5)
RANGE_TOLERANCE = 0.5
"""The TrajectoryFollower's default: within it, a waypoint is reached."""

Track = dict[str, list[tuple[float, np.ndarray]]]


def workers() -> list[ActorModel]:
    return [m for m in load_world(PEOPLE).models if isinstance(m, ActorModel)]


def corners(actor: ActorModel) -> list[np.ndarray]:
    """The script's waypoints in the world, its turns on the spot dropped, closed back at its start."""
    points: list[np.ndarray] = []
    for trajectory in actor.script.trajectories:
        for waypoint in trajectory.waypoints:
            point = (actor.pose.matrix() @ np.array([*waypoint.pose.xyz, 1.0]))[:2]
            if not points or np.linalg.norm(point - points[-1]) > 1e-6:
                points.append(point)
    return points


def desired_speed(actor: ActorModel) -> float:
    """The script's mean speed: its route's length over its duration (the plugin's default v0)."""
    points = corners(actor)
    length = sum(float(np.linalg.norm(b - a)) for a, b in zip(points, points[1:]))
    return length / sum(t.waypoints[-1].time - t.waypoints[0].time for t in actor.script.trajectories)


def chassis_gap(tug: dict, point: np.ndarray) -> float:
    """Metres from `point` to the tug's chassis (its rectangle on the floor)."""
    (x, y, _), (qx, qy, qz, qw) = tug["position"], tug["orientation"]
    yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return float(Boxes.of([(x, y, yaw, *TUG_HALF)]).nearest(point)[0][0])


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server("warehouse", "lockstep", extra=("--add", "warehouse_people")) as server:
        yield server


@pytest.fixture(autouse=True)
def fresh(sim: SimServer) -> Iterator[None]:
    yield
    sim.unsubscribe_all()


def watch(sim: SimServer, seconds: float, speed: float = 0.0) -> tuple[Track, list[dict]]:
    """From a reset, the tug driven at `speed`: each worker's position every SAMPLE_STEPS for
    `seconds`, and the tug's states."""
    sim.reset()
    sim.drive(speed)
    names = [a.name for a in workers()]
    tracks: Track = {name: [] for name in names}
    tugs = []
    for _ in range(round(seconds * 1000 / SAMPLE_STEPS)):
        sim.step(SAMPLE_STEPS)
        state = sim.state()
        for name in names:
            tracks[name].append((state["sim_time"], np.array(state["models"][name]["position"][:2])))
        tugs.append(state["models"]["flexley_tug"])
    return tracks, tugs


@pytest.fixture(scope="module")
def round_trip(sim: SimServer) -> tuple[Track, list[dict]]:
    """One round of every worker, the tug standing."""
    return watch(sim, ROUND_S)


def test_each_worker_goes_round_its_loop_reaching_every_corner_in_order(round_trip: tuple[Track, list[dict]]) -> None:
    tracks, _ = round_trip
    actors = workers()
    assert len(actors) == 3
    for actor in actors:
        points, speed, track = corners(actor), desired_speed(actor), tracks[actor.name]
        walked, index = 0.0, 0
        for previous, corner in zip(points, points[1:]):
            walked += float(np.linalg.norm(corner - previous))
            bound = ROUND_MARGIN * walked / speed + START_S
            reached = next(
                (
                    i
                    for i in range(index, len(track))
                    if np.linalg.norm(track[i][1] - corner) <= CROWD.waypoint_tolerance
                ),
                None,
            )
            assert reached is not None, f"{actor.name} never reached {corner} after {track[index][0]:.1f} s"
            assert track[reached][0] <= bound, (
                f"{actor.name} reached {corner} at {track[reached][0]:.1f} s, not by {bound:.1f} s"
            )
            index = reached
        print(f"\nmeasured: {actor.name} round in {track[index][0]:.1f} s (bound {bound:.1f} s)")


def test_a_worker_alone_keeps_to_its_line_and_clear_of_the_racks_pillars_and_work_cells(
    round_trip: tuple[Track, list[dict]],
) -> None:
    tracks, _ = round_trip
    warehouse = load_world(world_path("warehouse"))
    boxes = {k: v for m in warehouse.models if m.name != "floor" for k, v in collision_boxes(m).items()}
    for actor in workers():
        points = corners(actor)
        off = max(min(_off_segment(p, a, b) for a, b in zip(points, points[1:])) for _, p in tracks[actor.name])
        assert off <= OFF_LINE_M, f"{actor.name} strayed {off:.2f} m from its line"
        gap, nearest = min((planar_gap(p, box), name) for _, p in tracks[actor.name] for name, box in boxes.items())
        assert gap >= CROWD.radius, f"{actor.name} came {gap:.2f} m from {nearest}"
        print(f"\nmeasured: {actor.name} strayed at most {off:.2f} m, came {gap:.2f} m from {nearest}")


def _off_segment(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Metres from `point` to the segment a–b."""
    along = float(np.clip(np.dot(point - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0))
    return float(np.linalg.norm(point - (a + along * (b - a))))


def test_the_crossing_worker_passes_the_standing_tug_at_half_a_metre(round_trip: tuple[Track, list[dict]]) -> None:
    tracks, tugs = round_trip
    assert math.dist(tugs[-1]["position"][:2], TUG_SPAWN) < 0.01, "the tug did not stand"
    nearest = min(chassis_gap(tug, p) for tug, (_, p) in zip(tugs, tracks["worker_crossing"]))
    assert nearest >= 0.5, f"the crossing worker came {nearest:.2f} m from the tug's chassis"
    print(f"\nmeasured: the crossing worker passed {nearest:.2f} m from the standing tug's chassis")


def test_a_tug_driven_at_the_crossing_worker_never_has_a_worker_within_their_radius(sim: SimServer) -> None:
    """The tug at 0.5 m/s from its spawn meets the crossing worker's first leg (x −0.5) as it walks it."""
    tracks, tugs = watch(sim, 6.0, speed=0.5)
    sim.drive(0.0)
    assert tugs[-1]["position"][0] > TUG_SPAWN[0] + 2.0, "the tug did not drive"
    for name, track in tracks.items():
        nearest = min(chassis_gap(tug, p) for tug, (_, p) in zip(tugs, track))
        assert nearest >= CROWD.radius - STEP_TRAVEL - 1e-4, f"{name} came {nearest:.4f} m from the tug's chassis"


def test_each_workers_pose_topic_is_where_the_world_state_has_it(sim: SimServer) -> None:
    sim.reset()
    poses = {a.name: sim.subscribe(f"model/{a.name}/pose", POSE_STAMPED) for a in workers()}
    sim.prime(*poses.values())
    now_ns = round(sim.step(2000)["sim_time"] * 1e9)
    models = sim.state()["models"]
    for name, collector in poses.items():
        (x, y, z), _ = pose_of(collector.wait_stamp(now_ns, timeout=30.0, what=name).pose)
        assert math.dist((x, y, z), models[name]["position"]) < 0.01, f"{name} at {(x, y, z)}, the state says otherwise"


def test_the_cart_reaches_its_first_waypoint_and_heads_for_the_second(sim: SimServer) -> None:
    """From rest, 3.5 m to its first waypoint (about 8 s with 122 N against 118 N of friction), then
    turned on the spot and pushed east along y 2.5."""
    sim.reset()
    poses = sim.subscribe("model/cart/pose", POSE_STAMPED)
    sim.prime(poses)
    track: list[tuple[float, float]] = []
    for _ in range(16):
        now_ns = round(sim.step(1000)["sim_time"] * 1e9)
        poses.wait_stamp(now_ns, timeout=30.0, what="the cart's pose")
        track = [pose_of(m.pose)[0][:2] for m in poses.messages()]
        if track and track[-1][0] > CART_FIRST[0] + 0.5:
            break
    assert math.dist(track[0], CART_START) < 0.01, f"the cart started at {track[0]}"
    nearest = min(math.dist(p, CART_FIRST) for p in track)
    assert nearest < RANGE_TOLERANCE + 0.02, f"the cart came only within {nearest:.2f} m of {CART_FIRST}"
    x, y = track[-1]
    assert x > CART_FIRST[0] + 0.5 and abs(y - CART_SECOND[1]) < 0.3, f"the cart is at ({x:.2f}, {y:.2f})"
    print(f"\nmeasured: the cart came within {nearest:.2f} m of its first waypoint and was at ({x:.2f}, {y:.2f})")
