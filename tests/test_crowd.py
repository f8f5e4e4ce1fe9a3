"""A crowd that gives way (simbot.sim.systems.crowd, simbot.sim.kit.social_force).

The kit's arithmetic alone: two people walking head-on pass each other at least two radii apart;
a person alone takes up its desired speed within a few relaxation times and reaches its goal; a
wall farther than the obstacles' cutoff leaves a person on its line, a nearer one pushes it away.

Then a real server in lockstep (tests/fixtures/crowd.sdf, the tug at its spawn (−2.5, 0), its
chassis 2.1 × 0.5 m): `crosser`'s route runs across the standing tug, 0.2 m off its middle; it
goes round at ≥ 0.5 m from the chassis and reaches the far waypoint. Driven at `stander` (cmd_vel),
the tug never comes nearer any person than its radius (the hard constraint, less the 0.5 mm the
tug moves in one step). Two runs of one world give the same poses, bit for bit. A parameter out of
range leaves the plugin out with one line naming the actor and the element, and the actor walks
its script.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from server_helpers import REPO, SimServer, running_server

from simbot.description.crowd_params import Crowd
from simbot.sim.kit.social_force import (
    Boxes,
    Params,
    People,
    Route,
    Surroundings,
    accelerations,
    outside,
    steered,
    turned,
)

WORLD = REPO / "tests" / "fixtures" / "crowd.sdf"
DT = 1 / Crowd().update_rate
"""Seconds: the kit stepped as the plugin updates its forces."""
RADIUS = Crowd().radius
TUG_HALF = (1.05, 0.25)
"""The chassis collision box 2.1 × 0.5 m, centred on the model frame (SPEC.md)."""
DRIVE_SPEED, DRIVE_S = 0.5, 6.0
DRIVE_TOLERANCE_M = 0.06
"""How far from 0.5 m/s × 6 s the tug's drive through the people may end: it holds its speed within
1 % (its wheels' convex hulls roll 0.75 % wide) once at speed, which takes under 0.1 s (≤ 0.05 m
short: tests/test_client_teleop.py); people give way and never slow it (measured: 3.016 m)."""
STRAIGHT_M = 0.01
"""How far across its heading the tug may drift over the drive."""
STEP_TRAVEL = 0.5 * 0.001
"""Metres the tug driven at 0.5 m/s moves in one physics step (1 ms), after the person was placed."""
NONE = Boxes.of([])
NOBODY = np.zeros(0, np.int64)


def _among(people: People, obstacles: Boxes = NONE) -> Surroundings:
    """Everyone sees everyone else as they stand, moving as they do; `obstacles` near each of them."""
    count = len(people.positions)
    owners = np.repeat(np.arange(count), len(obstacles))
    return Surroundings(
        people.positions,
        np.broadcast_to(people.velocities, (count, count, 2)),
        ~np.eye(count, dtype=bool),
        Boxes.joined([obstacles] * count),
        owners,
        NONE,
        NOBODY,
    )


def _walk(crowd: Crowd, people: People, goals: np.ndarray, steps: int) -> list[People]:
    """`steps` steps of the kit's model for everyone at once, each seeing the others; every step's states."""
    rng = np.random.default_rng(3)
    params = Params.of((crowd,) * len(goals))
    arriving = np.zeros(len(goals), bool)
    track = []
    for _ in range(steps):
        accel = accelerations(params, people, goals, arriving, _among(people))
        kicks = rng.standard_normal((len(goals), 2)) * crowd.noise * math.sqrt(DT)
        velocities = steered(params, people.velocities, accel, DT, kicks)
        people = People(people.positions + velocities * DT, velocities, turned(params, people.yaws, velocities, DT))
        track.append(people)
    return track


def _standing(*positions: tuple[float, float], yaws: tuple[float, ...] = ()) -> People:
    count = len(positions)
    return People(np.array(positions, float), np.zeros((count, 2)), np.array(yaws or (0.0,) * count, float))


def test_two_people_walking_head_on_pass_each_other_two_radii_apart() -> None:
    crowd = Crowd()
    start = _standing((-5.0, 0.0), (5.0, 0.0), yaws=(0.0, math.pi))
    track = _walk(crowd, start, np.array([(6.0, 0.0), (-6.0, 0.0)]), round(14 / DT))
    nearest = min(float(np.hypot(*(state.positions[0] - state.positions[1]))) for state in track)
    assert nearest >= 2 * crowd.radius, f"they came {nearest:.3f} m apart"
    print(f"\nmeasured: they passed {nearest:.2f} m apart")
    a, b = track[-1].positions
    assert a == pytest.approx((6.0, 0.0), abs=0.05) and b == pytest.approx((-6.0, 0.0), abs=0.05)


def test_a_person_alone_takes_up_its_desired_speed_and_reaches_its_goal() -> None:
    crowd = Crowd()
    track = _walk(crowd, _standing((0.0, 0.0)), np.array([(20.0, 0.0)]), round(16 / DT))
    after = track[int(3 * crowd.relaxation_time / DT)]
    assert float(np.hypot(*after.velocities[0])) == pytest.approx(crowd.desired_speed, rel=0.06)
    assert min(float(np.hypot(*(state.positions[0] - (20.0, 0.0)))) for state in track) < crowd.waypoint_tolerance


def test_a_wall_beyond_the_cutoff_leaves_a_person_on_its_line_and_a_nearer_one_pushes_it_off() -> None:
    crowd = Crowd()
    params, goal, arriving = Params.of((crowd,)), np.array([(10.0, 0.0)]), np.zeros(1, bool)
    walker = People(np.zeros((1, 2)), np.array([(crowd.desired_speed, 0.0)]), np.zeros(1))
    alone = accelerations(params, walker, goal, arriving, _among(walker))
    for gap, pushed in ((crowd.obstacle_cutoff + 1e-3, False), (crowd.obstacle_cutoff / 2, True)):
        wall = Boxes.of([(0.0, crowd.radius + gap + 0.1, 0.0, 5.0, 0.1)])  # its face `gap` beyond the radius
        push = (accelerations(params, walker, goal, arriving, _among(walker, wall)) - alone)[0]
        assert (push[1] < 0) == pushed and push[0] == pytest.approx(0.0, abs=1e-12), (gap, push)


def test_people_thinking_together_feel_what_each_feels_thinking_alone() -> None:
    """One pass for a crowd is the sum of its people's own: each person's force among the others
    equals the force on it computed for it alone, seeing the same others and obstacles."""
    crowd = Crowd()
    rng = np.random.default_rng(7)
    people = People(rng.uniform(-2, 2, (6, 2)), rng.uniform(-1, 1, (6, 2)), np.zeros(6))
    goals, arriving = rng.uniform(-8, 8, (6, 2)), np.array([True, False] * 3)
    wall = Boxes.of([(0.0, 2.6, 0.2, 3.0, 0.1), (2.4, 0.0, 0.0, 0.1, 3.0)])
    together = accelerations(Params.of((crowd,) * 6), people, goals, arriving, _among(people, wall))
    for k in range(6):
        others = np.delete(people.positions, k, axis=0)
        motions = np.delete(people.velocities, k, axis=0)[None]
        alone = Surroundings(others, motions, np.ones((1, 5), bool), wall, np.zeros(2, np.int64), NONE, NOBODY)
        one = People(people.positions[k : k + 1], people.velocities[k : k + 1], np.zeros(1))
        force = accelerations(Params.of((crowd,)), one, goals[k : k + 1], arriving[k : k + 1], alone)
        assert together[k] == pytest.approx(force[0], rel=1e-12, abs=1e-12)


def test_the_hard_constraint_puts_a_person_outside_a_footprint_grown_by_its_radius() -> None:
    crowd = Crowd()
    tug = Boxes.of([(0.0, 0.0, 0.3, 1.05, 0.25)])
    for inside in ((0.0, 0.1), (1.0, -0.2), (0.2, 0.4)):
        point = outside(np.array([crowd.radius]), np.array([inside]), tug, np.zeros(1, np.int64))
        assert tug.nearest(point[0])[0][0] == pytest.approx(crowd.radius, abs=1e-9)


# --- the running world ---------------------------------------------------------------------


def _footprint_distance(state: dict, person: str) -> float:
    """Metres from the person's axis to the tug's chassis (its rectangle on the floor)."""
    tug, walker = state["models"]["flexley_tug"], state["models"][person]
    (x, y, _), (qx, qy, qz, qw) = tug["position"], tug["orientation"]
    yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    chassis = Boxes.of([(x, y, yaw, *TUG_HALF)])
    return float(chassis.nearest(np.array(walker["position"][:2]))[0][0])


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server(str(WORLD), "lockstep") as server:
        yield server


def _run(sim: SimServer, seconds: float) -> list[dict]:
    """World states every 0.1 s for `seconds`."""
    states = []
    for _ in range(round(seconds / 0.1)):
        sim.step(100)
        states.append(sim.state())
    return states


def test_a_worker_crossing_the_standing_tug_goes_round_it_and_rejoins_its_route(sim: SimServer) -> None:
    sim.reset()
    states = _run(sim, 12.0)
    nearest = min(_footprint_distance(state, "crosser") for state in states)
    assert nearest >= 0.5, f"the crosser came {nearest:.3f} m from the tug's chassis"
    print(f"\nmeasured: the crosser passed {nearest:.2f} m from the tug's chassis")
    far = min(math.dist(state["models"]["crosser"]["position"][:2], (-2.3, 3.0)) for state in states)
    assert far <= Crowd().waypoint_tolerance + 0.05, f"the crosser came no nearer its far waypoint than {far:.2f} m"


def test_a_tug_driven_at_a_person_never_comes_nearer_than_its_radius(sim: SimServer) -> None:
    sim.reset()
    start = sim.state()["models"]["flexley_tug"]["position"]
    sim.drive(DRIVE_SPEED)
    states = _run(sim, DRIVE_S)
    sim.drive(0.0)
    end = states[-1]["models"]["flexley_tug"]["position"]
    assert end[0] - start[0] == pytest.approx(DRIVE_SPEED * DRIVE_S, abs=DRIVE_TOLERANCE_M), (
        f"the tug drove {end[0] - start[0]:.3f} m through the stander's place, not {DRIVE_SPEED * DRIVE_S} m"
    )
    assert abs(end[1] - start[1]) < STRAIGHT_M, "the tug drove straight along x"
    for person in ("stander", "crosser"):
        nearest = min(_footprint_distance(state, person) for state in states)
        assert nearest >= RADIUS - STEP_TRAVEL - 1e-4, f"{person} came {nearest:.4f} m from the tug's chassis"


def _poses(seconds: float) -> dict[str, list[float]]:
    with running_server(str(WORLD), "lockstep") as server:
        server.step(round(seconds * 1000))
        models = server.state()["models"]
    return {name: [*models[name]["position"], *models[name]["orientation"]] for name in ("crosser", "stander")}


def test_two_lockstep_runs_give_the_same_poses_bit_for_bit() -> None:
    first, second = _poses(1.0), _poses(1.0)
    assert first == second


def test_a_parameter_out_of_range_leaves_the_plugin_out_and_the_actor_walks_its_script(tmp_path: Path) -> None:
    world = tmp_path / "crowd_bad.sdf"
    world.write_text(
        WORLD.read_text().replace("<relaxation_time>0.5</relaxation_time>", "<relaxation_time>-1</relaxation_time>")
    )
    with running_server(str(world), "lockstep", world_name="crowd") as server:
        server.step(1000)
        (x, y, _), _ = server.pose("crosser")
        errors = server.errors()
    lines = [line for line in errors if "crosser" in line]
    assert len(lines) == 1 and "<relaxation_time>" in lines[0], errors
    # its script: from (−2.3, −3) to (−2.3, 3) in 7.5 s at tension 1 (eased in: s² (3 − 2s) of the way)
    s = 1.0 / 7.5
    assert (x, y) == pytest.approx((-2.3, -3.0 + 6.0 * s * s * (3 - 2 * s)), abs=0.01)


def test_a_person_starting_part_of_the_way_round_walks_on() -> None:
    """A randomised world may start a person part of the way round its loop (simbot.variation's phase):
    its first goal is the end of the leg it stands on, not the loop's first point."""
    square = Route.of([(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0), (0.0, 0.0)], loop=True)
    assert square.ahead(np.array([0.0, 0.0]), 0.3) == 1
    assert square.ahead(np.array([3.0, 0.0]), 0.3) == 1
    assert square.ahead(np.array([4.0, 2.5]), 0.3) == 2
    assert square.ahead(np.array([0.0, 1.0]), 0.3) == 0
    assert square.ahead(np.array([3.9, 0.0]), 0.3) == 2, "within the tolerance of a corner: on to the next"
