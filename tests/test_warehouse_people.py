"""The warehouse with its people (`simbot-server --add warehouse_people`, what `make run` starts).

One server in lockstep: the warehouse, the tug, and worlds/additions/warehouse_people.sdf added.
Each worker's ground truth on `model/<name>/pose` is where its script puts it at the message's sim
time (simbot.sim.kit.actor_paths, the model of truth: within 1 cm, PyBullet's single-precision
transforms are micrometres), and the cart, pushed by its TrajectoryFollower from rest, reaches its
first waypoint and heads on for the second.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from server_helpers import POSE_STAMPED, REPO, SimServer, pose_of, running_server

from simbot.description import load_world
from simbot.description.actor_scripts import ActorModel
from simbot.sim.kit.actor_paths import ScriptPath

PEOPLE = REPO / "worlds" / "additions" / "warehouse_people.sdf"
TIMES_S = (3.0, 10.0)
"""Two sim times to compare the workers at: 3 s into every first leg, and 10 s, past a corner for the crossing worker."""
CART_START, CART_FIRST, CART_SECOND = (5.8, -1.0), (5.8, 2.5), (8.5, 2.5)
RANGE_TOLERANCE = 0.5
"""The TrajectoryFollower's default: within it, a waypoint is reached."""


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server("warehouse", "lockstep", extra=("--add", "warehouse_people")) as server:
        yield server


@pytest.fixture(autouse=True)
def fresh(sim: SimServer) -> Iterator[None]:
    sim.reset()
    yield
    sim.unsubscribe_all()


def workers() -> list[ActorModel]:
    return [m for m in load_world(PEOPLE).models if isinstance(m, ActorModel)]


def scripted(actor: ActorModel, sim_time: float) -> np.ndarray:
    """Where the actor's script puts it in the world: its frame composed with the trajectory's pose."""
    position = ScriptPath.of(actor.script).pose_at(sim_time).position
    return (actor.pose.matrix() @ np.array([*position, 1.0]))[:3]


def test_each_worker_walks_its_loop_where_its_script_puts_it(sim: SimServer) -> None:
    actors = workers()
    assert len(actors) == 3
    poses = {a.name: sim.subscribe(f"model/{a.name}/pose", POSE_STAMPED) for a in actors}
    sim.prime(*poses.values())
    seen: dict[str, list[np.ndarray]] = {a.name: [] for a in actors}
    for sim_time in TIMES_S:
        sim.step(round(sim_time * 1000) - sim.state()["iterations"])
        for name, collector in poses.items():
            seen[name].append(
                np.array(pose_of(collector.wait_stamp(round(sim_time * 1e9), timeout=30.0, what=name).pose)[0])
            )
    for actor in actors:
        (at_1, at_2), (want_1, want_2) = seen[actor.name], (scripted(actor, t) for t in TIMES_S)
        assert np.linalg.norm(at_1 - want_1) < 0.01, f"{actor.name} at {at_1}, its script says {want_1}"
        assert np.linalg.norm(at_2 - want_2) < 0.01, f"{actor.name} at {at_2}, its script says {want_2}"
        assert np.linalg.norm((at_2 - at_1) - (want_2 - want_1)) < 0.01, f"{actor.name} walked off its script"
        assert np.linalg.norm(at_2 - at_1) > 3.0, f"{actor.name} walked only {np.linalg.norm(at_2 - at_1):.2f} m"
    print("\nmeasured: " + ", ".join(f"{n} walked {np.linalg.norm(p[1] - p[0]):.2f} m" for n, p in seen.items()))


def test_the_cart_reaches_its_first_waypoint_and_heads_for_the_second(sim: SimServer) -> None:
    """From rest, 3.5 m to its first waypoint (about 8 s with 122 N against 118 N of friction), then
    turned on the spot and pushed east along y 2.5."""
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
