"""The physics module alone (no bus): poses by name, wheel friction bounded by load, the detachable joint."""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Iterator
from pathlib import Path

import pybullet as pb
import pytest
from conftest import ROBOT_SDF, TROLLEY_SDF
from test_sim_shapes import CONTACT_SLOP, FIXTURES

from simbot.description import load_model, load_world
from simbot.description.model import Box, Collision, Inertial, Link, Model, Sphere
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.physics import Physics
from simbot.sim.physics.kinematic_world import KINEMATIC_STEP_S, KinematicWorld, kinematic
from simbot.sim.physics.steady_turn import Chassis, steady_turn, turn_centre
from simbot.sim.physics.stepping import DynamicStepper, stepper
from simbot.transform import Transform, yaw_of

G = 9.8
ROBOT_MASS = 100 + 4 * 0.765 + 4 * 0.103 + 2 * 1.17 + 0.001  # chassis, wheels, castors, lidars, token root
WHEELS = ("front_left_wheel_joint", "back_left_wheel_joint", "front_right_wheel_joint", "back_right_wheel_joint")
RADIUS = 0.075


@pytest.fixture
def physics() -> Iterator[Physics]:
    """The empty world with the robot at the origin, settled for 0.5 s."""
    world = load_world(asset("worlds/empty.sdf"))
    sim = Physics(world)
    for model in world.models:
        sim.add_model(model)
    sim.add_model(load_model(ROBOT_SDF), "flexley_tug", Pose((0.0, 0.0, 0.1)))
    _run(sim, 0.5)
    yield sim
    sim.close()


def _run(sim: Physics, seconds: float) -> None:
    for _ in range(round(seconds / sim.step_size)):
        sim.step()


def _drive(sim: Physics, left: float, right: float) -> None:
    """Wheel surface speeds in m/s on each side."""
    for joint in WHEELS:
        speed = left if "left" in joint else right
        sim.set_joint_velocity("flexley_tug", joint, speed / RADIUS, 10000.0)


def test_the_world_asks_for_its_stepping_once() -> None:
    """Dynamic unless the world's physics is kinematic, which steps at the kinematic world's step."""
    world = load_world(asset("worlds/empty.sdf"))
    client = pb.connect(pb.DIRECT)
    dynamic, kinematic_ = stepper(world, client), stepper(kinematic(world), client)
    pb.disconnect(client)
    assert isinstance(dynamic, DynamicStepper)
    assert isinstance(kinematic_, KinematicWorld) and kinematic_.dt == KINEMATIC_STEP_S


def test_model_pose_is_the_model_frame_not_the_centre_of_mass() -> None:
    """The trolley's centre of mass is 0.58 m up; its model frame stands on the floor."""
    world = load_world(asset("worlds/empty.sdf"))
    sim = Physics(world)
    for model in world.models:
        sim.add_model(model)
    sim.add_model(load_model(TROLLEY_SDF), "trolley", Pose((1.0, 0.2, 0.0), (0.0, 0.0, 0.3)))
    _run(sim, 0.5)
    (x, y, z), quat = sim.model_pose("trolley")
    assert (x, y) == pytest.approx((1.0, 0.2), abs=0.005)
    assert z == pytest.approx(0.0, abs=0.005)
    assert yaw_of(quat) == pytest.approx(0.3, abs=0.005)
    sim.set_model_pose("trolley", Transform((-1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
    assert sim.model_pose("trolley")[0] == pytest.approx((-1.0, 2.0, 0.0), abs=1e-6)
    sim.close()


def test_robot_stands_still_with_held_wheels(physics: Physics) -> None:
    """Wheels held at zero speed: after 2 s the robot has not crept a millimetre."""
    _drive(physics, 0.0, 0.0)
    start = physics.model_pose("flexley_tug")[0]
    _run(physics, 2.0)
    assert math.dist(start, physics.model_pose("flexley_tug")[0]) < 1e-3


def test_rolling_without_slip_matches_the_wheels(physics: Physics) -> None:
    """0.5 m/s on both sides for 2 s: 1.0 m within 1 % (measured 0.997: the wheels roll, they do not slide)."""
    _drive(physics, 0.5, 0.5)
    start = physics.model_pose("flexley_tug")[0]
    _run(physics, 2.0)
    assert math.dist(start[:2], physics.model_pose("flexley_tug")[0][:2]) == pytest.approx(1.0, rel=0.01)


def test_turns_in_place_despite_four_wheels(physics: Physics) -> None:
    """±0.1 m/s (0.5 rad/s commanded) for 4 s: the steady turn's yaw rate (the derivation: 91 % of
    the command) once up to speed, after ~0.3 s, within 5 %; with isotropic friction it would be
    0.006 rad.

    Scrubbing four wheels sideways (μ2 0.25 at x ±0.58) costs 0.725 N of traction per newton of
    load against 0.9 available, so the wheels slip a little. Every tyre slides sideways, so where
    the turn is centred along x is free (docs/robot.md); across, the wheels' slip is small and the
    forces balance at y = (0.2ω − 0.1)/ω · (N_left − N_right)/N, within 1.7 cm even with all the
    load on one side."""
    derived = steady_turn(Chassis.of(load_model(ROBOT_SDF)), 0.0, 0.5)
    _drive(physics, -0.1, 0.1)
    start = physics.model_pose("flexley_tug")
    heading, turned = yaw_of(start[1]), 0.0
    for step in range(4000):
        physics.step()
        if step == 499:  # up to speed
            steady = physics.model_pose("flexley_tug")
        now = yaw_of(physics.model_pose("flexley_tug")[1])
        turned += math.remainder(now - heading, math.tau)
        heading = now
    assert turned == pytest.approx(derived.yaw_rate * (4.0 - 0.3), rel=0.05)
    _, centre_y = turn_centre(steady, physics.model_pose("flexley_tug"))
    assert abs(centre_y) < (0.1 - 0.2 * derived.yaw_rate) / derived.yaw_rate


@pytest.mark.parametrize(("speed", "radius"), [(0.5, 3.0), (1.0, 6.0), (0.3, 1.5)])
def test_a_turn_is_centred_where_the_loads_put_it(physics: Physics, speed: float, radius: float) -> None:
    """A steady turn of the DiffDrive's wheel speeds, measured over 4 s after 3 s to settle, is the
    one the SDF's loads and tyres imply (`steady_turn`, docs/robot.md): its centre within 5 cm of
    the derived one, the body's sideways slip that centre's offset over the radius (so within
    5 cm / R of the derived slip, and at most 1 % at 3 m and 0.5 m/s), the yaw rate and the wheel
    odometry's yaw rate over the true one within 10 % of the derivation's."""
    derived = steady_turn(Chassis.of(load_model(ROBOT_SDF)), speed, speed / radius, physics.step_size)
    half = speed / radius * 0.4 / 2
    _drive(physics, speed - half, speed + half)
    _run(physics, 3.0)
    before = physics.model_pose("flexley_tug")
    angles = [s[0] for s in physics.joint_states("flexley_tug", list(WHEELS))]
    _run(physics, 4.0)
    after = physics.model_pose("flexley_tug")
    wheels = [s[0] - a for s, a in zip(physics.joint_states("flexley_tug", list(WHEELS)), angles)]
    turn = math.remainder(yaw_of(after[1]) - yaw_of(before[1]), math.tau)
    pivot, _ = turn_centre(before, after)
    chord = math.dist(before[0][:2], after[0][:2])
    odometry_turn = ((wheels[2] + wheels[3]) - (wheels[0] + wheels[1])) / 2 * RADIUS / 0.4
    slip = abs(pivot) * abs(turn) / chord  # the model frame's sideways over forward speed
    assert pivot == pytest.approx(derived.pivot, abs=0.05)
    assert slip == pytest.approx(derived.side_slip, abs=0.05 / radius)
    assert turn / 4.0 == pytest.approx(derived.yaw_rate, rel=0.10)
    assert odometry_turn / turn == pytest.approx(derived.odom_yaw_ratio, rel=0.10)
    if (speed, radius) == (0.5, 3.0):
        assert slip <= 0.01


def test_a_wall_pushes_back_and_traction_is_bounded_by_friction(physics: Physics) -> None:
    """Driven into a wall, the robot stops, its wheels spin on, and the wall holds it with no more than μ·m·g."""
    wall = Model("wall", static=True, links=(Link("box", collisions=(Collision("c", Box((0.2, 4.0, 1.0))),)),))
    physics.add_model(wall, pose=Pose((1.5, 0.0, 0.5)))  # the chassis front is at x 1.05
    _drive(physics, 0.5, 0.5)
    _run(physics, 3.0)
    x = physics.model_pose("flexley_tug")[0][0]
    assert x == pytest.approx(1.5 - 0.1 - 1.05, abs=0.005), "the wall stops the chassis"  # measured 1 mm into the wall
    angle_before = physics.joint_states("flexley_tug", ["front_left_wheel_joint"])[0][0]
    _run(physics, 1.0)
    spun = physics.joint_states("flexley_tug", ["front_left_wheel_joint"])[0][0] - angle_before
    assert spun * RADIUS == pytest.approx(0.5, rel=0.01), "the wheels keep turning, slipping on the floor"
    body, wall_id = physics.body("flexley_tug").id, physics.body("wall").id
    pushes = []
    for _ in range(500):  # the chassis chatters on the wall (0.4-3 kN from step to step): take the mean over 0.5 s
        physics.step()
        pushes.append(sum(c[9] for c in pb.getContactPoints(body, wall_id, physicsClientId=physics.client)))
    # μ·m·g from the wheels (measured 1.057 μmg): the wall's friction on the chassis presses it down,
    # adding load and so traction; ±10 % covers that and the chatter's mean over 0.5 s
    assert sum(pushes) / len(pushes) == pytest.approx(1.05 * 0.9 * ROBOT_MASS * G, rel=0.10)


def test_attach_holds_the_relative_pose_and_detach_frees(physics: Physics) -> None:
    """A trolley fixed to base_link follows the robot 1 m; once detached it slides to a stop and stays behind."""
    physics.add_model(load_model(TROLLEY_SDF), "trolley", Pose((0.0, 0.1, 0.0)))
    _run(physics, 0.3)
    joint = physics.attach(("flexley_tug", "base_link"), ("trolley", "base"))
    trolley0 = physics.model_pose("trolley")[0]
    _drive(physics, 0.5, 0.5)
    _run(physics, 2.0)
    trolley1 = physics.model_pose("trolley")[0]
    # Up to speed, 0.5 m/s for 2 s: 1.0 m, less the start's lag v²/2a, 1.4 cm with all the weight on
    # the wheels (a = μg 8.8 m/s²). Fixed to a trolley standing on its own feet, the eight supports
    # share the weight as fractions of a millimetre decide (statically indeterminate): less on the
    # wheels, less traction, a longer start (measured 1.3 cm with the castor gimbals, 2.6 cm merged).
    # 4 cm bounds a start with only a third of the weight on the wheels.
    assert 1.0 - 0.04 < trolley1[0] - trolley0[0] < 1.0 + 0.01
    assert trolley1[2] == pytest.approx(trolley0[2], abs=0.01), "carried at its height"
    physics.detach(joint)
    _run(physics, 1.5)
    slid = physics.model_pose("trolley")[0][0] - trolley1[0]
    assert slid == pytest.approx(0.5**2 / (2 * 0.05 * G), rel=0.06), (
        "freed at 0.5 m/s, it slides v²/(2μg) on μ 0.05 feet"
    )  # measured −3 %
    _run(physics, 1.0)
    assert physics.model_pose("trolley")[0][0] - trolley1[0] == pytest.approx(slid, abs=0.005), (
        "then stands while the robot drives on"
    )
    assert physics.model_pose("flexley_tug")[0][0] > trolley1[0] + 1.0


def test_a_removed_heightmap_leaves_nothing_to_land_on() -> None:
    """The terrain's heightfield (a PyBullet body of its own) goes with its model: a ball dropped from
    3 m where the surface stood at 1.92 m (tests/test_sim_shapes.py) falls through to the floor and
    rests on it at its radius, and the world holds as many bodies as before the terrain came."""
    world = load_world(asset("worlds/empty.sdf"))
    sim = Physics(world)
    for model in world.models:
        sim.add_model(model)
    bodies = pb.getNumBodies(physicsClientId=sim.client)
    sim.add_model(load_world(FIXTURES / "heightmap.sdf").model("terrain"))
    sim.remove_model("terrain")
    left = pb.getNumBodies(physicsClientId=sim.client)
    radius = 0.1
    ball = Link("ball", inertial=Inertial(1.0), collisions=(Collision("c", Sphere(radius)),))
    sim.add_model(Model("ball", links=(ball,)), pose=Pose((1.0, 2.0, 3.0)))
    _run(sim, 1.5)  # a fall of 2.9 m takes 0.77 s
    (x, y, z), _ = sim.model_pose("ball")
    sim.close()
    assert z == pytest.approx(radius, abs=CONTACT_SLOP)
    assert (x, y) == pytest.approx((1.0, 2.0), abs=1e-6)
    assert left == bodies


def _tug_with_slip(tmp_path: Path, slip1: str | None, slip2: str | None) -> Path:
    """The tug's SDF, its front left wheel stating `<slip1>`/`<slip2>` where given (beside its
    meshes, which it finds relative to itself)."""
    text = ROBOT_SDF.read_text()
    stated = "".join(f"<{tag}>{value}</{tag}>" for tag, value in (("slip1", slip1), ("slip2", slip2)) if value)
    wheel = text.index('<link name="front_left_wheel">')
    at = text.index("<fdir1>", wheel)
    path = ROBOT_SDF.parent / f".slip_{tmp_path.name}.sdf"
    path.write_text(text[:at] + stated + text[at:])
    return path


def test_sdf_force_dependent_slip_is_read(tmp_path: Path) -> None:
    """ODE's `<slip1>`/`<slip2>` (m/s per N) reach the wheel's friction; unstated, SDF's 0."""
    path = _tug_with_slip(tmp_path, "0.002", "5e-4")
    try:
        model = load_model(path)
    finally:
        path.unlink()
    frictions = {link.name: link.collisions[0].friction for link in model.links if link.name.endswith("_wheel")}
    front_left, back_left = frictions["front_left_wheel"], frictions["back_left_wheel"]
    assert front_left is not None and back_left is not None
    assert (front_left.slip1, front_left.slip2) == (0.002, 5e-4)
    assert (back_left.slip1, back_left.slip2) == (0.0, 0.0)


@pytest.mark.parametrize("bad", ["-0.01", "fast", "nan"])
def test_a_bad_slip_is_one_line_and_the_default(tmp_path: Path, caplog: pytest.LogCaptureFixture, bad: str) -> None:
    """A negative or non-numeric slip: one warning naming the model, link and element; the world loads with SDF's 0."""
    path = _tug_with_slip(tmp_path, None, bad)
    try:
        with caplog.at_level(logging.WARNING):
            model = load_model(path)
    finally:
        path.unlink()
    wheel = next(link for link in model.links if link.name == "front_left_wheel")
    friction = wheel.collisions[0].friction
    assert friction is not None and friction.slip2 == 0.0
    lines = [r.getMessage() for r in caplog.records if "slip2" in r.getMessage()]
    assert len(lines) == 1
    assert all(part in lines[0] for part in ("'flexley_tug'", "'front_left_wheel'", "<slip2>", repr(bad)))


def test_a_stated_slip_is_the_tyre_the_turn_follows(physics: Physics) -> None:
    """Every wheel stating slip2 = 4 mm/s per N (a side stiffness of 250 N·s/m, where the default's
    is 620 at 0.5 m/s; still linear at the 0.1 m/s the wheels scrub at on a 3 m radius) turns
    where the derivation with that slip puts it: the centre further ahead, carrying the
    centripetal force on softer tyres (m·v / 4k = 5.3 cm against 2.3)."""
    model = load_model(ROBOT_SDF)
    soft = model.with_wheel_friction(lambda f: dataclasses.replace(f, slip2=4e-3))
    chassis = Chassis.of(soft)
    derived, default = steady_turn(chassis, 0.5, 0.5 / 3.0), steady_turn(Chassis.of(model), 0.5, 0.5 / 3.0)
    assert abs(derived.pivot - default.pivot) > 0.02, "the stated slip must make a difference the test can see"
    physics.remove_model("flexley_tug")
    physics.add_model(soft, "flexley_tug", Pose((0.0, 0.0, 0.1)))
    _run(physics, 0.5)
    half = 0.5 / 3.0 * 0.4 / 2
    _drive(physics, 0.5 - half, 0.5 + half)
    _run(physics, 3.0)
    before = physics.model_pose("flexley_tug")
    _run(physics, 4.0)
    pivot, _ = turn_centre(before, physics.model_pose("flexley_tug"))
    assert pivot == pytest.approx(derived.pivot, abs=0.01)


def test_the_robot_page_states_the_derived_turns() -> None:
    """docs/robot.md's table of steady turns is what `steady_turn` derives from the SDF, to its digits."""
    page = (Path(__file__).resolve().parents[1] / "docs" / "robot.md").read_text()
    table = page[page.index("| speed, m/s | radius, m |") :].split("\n\n", 1)[0].splitlines()[2:]
    chassis = Chassis.of(load_model(ROBOT_SDF))
    assert len(table) == 7
    for row in table:
        speed, radius = (float(cell) for cell in row.split("|")[1:3])
        turn = steady_turn(chassis, speed, speed / radius)
        derived = (
            f"| {speed:g} | {radius:g} | {turn.pivot:.3f} | {turn.side_slip:.2%} | {turn.radius:.2f} | "
            f"{turn.yaw_ratio:.3f} | {turn.odom_yaw_ratio:.3f} |"
        )
        assert row == derived
