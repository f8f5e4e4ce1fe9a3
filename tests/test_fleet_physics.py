"""The loader's ball castors (issue 17, item 4): which joints count as one, and that a tug loaded
with its castors fixed keeps its indices and drives as before; a castor pressed to the floor holds.

The tug (SPEC §1): wheels r 0.075 at x ±0.58 carry it; castors r 0.025 at x 0.92 and −0.79 hang
2 cm above the floor. Pushed down at its front end (x 1.05) by F, it tips onto its front castors
once F · (1.05 − 0.58) exceeds its weight's moment about the front axle, 110 kg · g · 0.58 m:
F > 1.3 kN. Then each front castor carries load and its sphere rests on the floor, its centre a
radius up (within Bullet's few millimetres of contact slop).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import pybullet as pb
import pytest
from conftest import ROBOT_SDF

from simbot.description import load_model, load_world
from simbot.description.model import Box, Collision, Joint, Link, Model, Sphere
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.physics import Physics, ball_castors

CASTORS = ("castor_front_right", "castor_front_left", "castor_back_right", "castor_back_left")
WHEELS = ("front_left_wheel_joint", "back_left_wheel_joint", "front_right_wheel_joint", "back_right_wheel_joint")
RADIUS, CASTOR_RADIUS = 0.075, 0.025
SETTLE_S = 0.5


LOADERS = {"gimbals": (False, False), "fixed": (True, False), "lean": (True, True)}
"""(fixed_castors, merge_fixed_links): the castors' gimbals simulated; fixed; fixed and merged (the default)."""


def _physics(fixed_castors: bool, merge_fixed_links: bool) -> Physics:
    world = load_world(asset("worlds/empty.sdf"))
    physics = Physics(world, fixed_castors=fixed_castors, merge_fixed_links=merge_fixed_links)
    for model in world.models:
        physics.add_model(model)
    physics.add_model(load_model(ROBOT_SDF), "flexley_tug", Pose((0.0, 0.0, 0.1)))
    return physics


@pytest.fixture(params=list(LOADERS))
def physics(request: pytest.FixtureRequest) -> Iterator[Physics]:
    sim = _physics(*LOADERS[request.param])
    _run(sim, SETTLE_S)
    yield sim
    sim.close()


def _run(sim: Physics, seconds: float) -> None:
    for _ in range(round(seconds / sim.step_size)):
        sim.step()


def test_the_tugs_ball_castors_and_only_those() -> None:
    """The tug's four castor joints; not a ball joint whose sphere is off its centre, whose link has a box, or that has a child."""
    assert ball_castors(load_model(ROBOT_SDF)) == {f"{name}_joint" for name in CASTORS}
    ball = Joint("ball", "ball", "base", "ball_link", Pose((1.0, 0.0, 0.0)))

    def model(*collisions: Collision, more: tuple[Joint, ...] = ()) -> Model:
        links = (Link("base"), Link("ball_link", Pose((1.0, 0.0, 0.0)), collisions=collisions), Link("tip"))
        return Model("m", links=links, joints=(ball, *more))

    assert ball_castors(model(Collision("c", Sphere(0.1)))) == {"ball"}
    assert not ball_castors(model(Collision("c", Sphere(0.1), Pose((0.0, 0.0, 0.05)))))
    assert not ball_castors(model(Collision("c", Box((0.1, 0.1, 0.1)))))
    assert not ball_castors(model(Collision("c", Sphere(0.1)), more=(Joint("j", "fixed", "ball_link", "tip"),)))


def test_lean_loading_keeps_every_name_and_the_drive() -> None:
    """Loaded lean (castors fixed, fixed links merged: 5 PyBullet links of 21), every link still has
    its pose by name, the same as with the gimbals as loaded (to PyBullet's float32); the castor gimbals read 0 and
    the renderer gets every joint of the published URDF; 0.5 m/s for 2 s rolls 1.0 m within 1 % either way."""
    gimbals, lean = _physics(*LOADERS["gimbals"]), _physics(*LOADERS["lean"])
    try:
        tug, tug_lean = gimbals.body("flexley_tug"), lean.body("flexley_tug")
        assert pb.getNumJoints(tug_lean.id, physicsClientId=lean.client) == 4
        assert set(tug.links) == set(tug_lean.links) >= {link.name for link in tug.model.links}
        for link in (link.name for link in tug.model.links):
            position, orientation = lean.frame_pose("flexley_tug", link)
            expected = gimbals.frame_pose("flexley_tug", link)
            assert position == pytest.approx(expected[0], abs=1e-6), link
            assert orientation == pytest.approx(expected[1], abs=1e-6), link
        gimbal_joints = sorted(name for name in tug.joints if name.startswith("castor_") and "__" in name)
        assert len(gimbal_joints) == 12 and sorted(tug_lean.held) == gimbal_joints
        assert lean.body_state("flexley_tug")[1].keys() == gimbals.body_state("flexley_tug")[1].keys()
        travelled = []
        for sim in (gimbals, lean):
            _run(sim, SETTLE_S)
            for joint in WHEELS:
                sim.set_joint_velocity("flexley_tug", joint, 0.5 / RADIUS, 10000.0)
            start = sim.model_pose("flexley_tug")[0]
            _run(sim, 2.0)
            travelled.append(math.dist(start[:2], sim.model_pose("flexley_tug")[0][:2]))
        assert travelled == pytest.approx([1.0, 1.0], rel=0.01)
        assert all(state == (0.0, 0.0, 0.0) for state in lean.joint_states("flexley_tug", gimbal_joints))
    finally:
        gimbals.close()
        lean.close()


def test_a_castor_pressed_to_the_floor_holds(physics: Physics) -> None:
    """Pushed down at the front end with 3 kN (tipping takes 1.3 kN), the tug rests on its front
    castors: each carries load, frictionless, its centre one radius (0.025 m) above the floor within 3 mm."""
    body = physics.body("flexley_tug")
    for _ in range(round(1.0 / physics.step_size)):
        front_top = physics.frame_pose("flexley_tug", "base_link", Pose((1.05, 0.0, 0.115)))[0]
        pb.applyExternalForce(
            body.id, -1, (0.0, 0.0, -3000.0), front_top, pb.WORLD_FRAME, physicsClientId=physics.client
        )
        physics.step()
    for castor in ("castor_front_left", "castor_front_right"):
        centre = physics.frame_pose("flexley_tug", castor)[0]
        contacts = [
            c
            for c in pb.getContactPoints(bodyA=body.id, linkIndexA=body.links[castor], physicsClientId=physics.client)
            if math.dist(c[5][:2], centre[:2]) < CASTOR_RADIUS  # a merged castor's host touches elsewhere too
        ]
        assert sum(c[9] for c in contacts) > 0, f"{castor} carries nothing"
        assert centre[2] == pytest.approx(CASTOR_RADIUS, abs=0.003), castor
        if body.hosts[castor] == castor:  # merged, it rubs with its host's μ (the chassis's: SDF's default 1)
            assert pb.getDynamicsInfo(body.id, body.links[castor], physicsClientId=physics.client)[1] == 0.0, "μ"
