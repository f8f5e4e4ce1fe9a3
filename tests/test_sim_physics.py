"""The physics module alone (no bus): poses by name, wheel friction bounded by load, the detachable joint."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pybullet as pb
import pytest
from conftest import ROBOT_SDF, TROLLEY_SDF
from test_sim_shapes import CONTACT_SLOP, FIXTURES

from simbot.description import load_model, load_world
from simbot.description.model import Box, Collision, Inertial, Link, Model, Sphere
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.physics import Physics
from simbot.sim.physics.kinematic_stepper import KINEMATIC_STEP_S, KinematicStepper, kinematic
from simbot.sim.physics.stepping import DynamicStepper, stepper
from simbot.transform import yaw_of

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
    assert isinstance(kinematic_, KinematicStepper) and kinematic_.dt == KINEMATIC_STEP_S


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
    sim.set_model_pose("trolley", ((-1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
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
    """±0.1 m/s (0.5 rad/s commanded) for 4 s: 1.70 rad ± 5 %; with isotropic friction it would be 0.006 rad.

    The figure follows from the friction: scrubbing four wheels sideways (μ2 0.25 at x ±0.58) costs
    0.725 N of traction per newton of load against 0.9 available, so the wheels slip a little and
    the robot turns at about 92 % of the command once up to speed, after ~0.3 s: 0.92 × 0.5 × 3.7
    = 1.70 rad (measured 1.696).

    Where it turns about follows from the friction too. Across the wheels, friction is saturated
    (the wheels scrub sideways at ω·0.58 ≈ 0.27 m/s, the regularising slip is 0.01 m/s), so the
    sideways forces balance wherever the centre lies between the axles: |x| < 0.58 − 0.01/ω = 0.56 m.
    Along them, slip stays under 0.01 m/s (0.1 − 0.2ω = 0.008 m/s) and friction is linear in it:
    the forces balance at y = (0.2ω − 0.1)/ω · (N_left − N_right)/N, within 1.7 cm even with all the
    load on one side. So the robot drifts: measured centres within 4.6 cm along x and 0.7 cm
    across over six start headings."""
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
    assert turned == pytest.approx(0.92 * 0.5 * (4.0 - 0.3), rel=0.05)
    centre_x, centre_y = _turning_centre(steady, physics.model_pose("flexley_tug"))
    assert abs(centre_x) < 0.58 - 0.01 / (0.92 * 0.5)
    assert abs(centre_y) < (0.1 - 0.2 * 0.92 * 0.5) / (0.92 * 0.5)


def _turning_centre(
    before: tuple[tuple[float, ...], tuple[float, ...]], after: tuple[tuple[float, ...], tuple[float, ...]]
) -> tuple[float, float]:
    """The point (in the robot's frame at `before`) that a rigid turn from `before` to `after` keeps in place."""
    turn = yaw_of(after[1]) - yaw_of(before[1])
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    p0, p1 = np.asarray(before[0][:2]), np.asarray(after[0][:2])
    centre = np.linalg.solve(np.eye(2) - rotation, p1 - rotation @ p0)  # p1 = c + R (p0 − c)
    yaw = yaw_of(before[1])
    x, y = np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]]) @ (centre - p0)
    return float(x), float(y)


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
