"""Navigate-v0 with `physics="kinematic"` (issue 47, item 1): the server's kinematic stepper moves
the robot by its drive's command at 200 Hz, so an env step of 0.1 s is 20 physics steps instead of
100, with the same spaces, rewards and collisions.

Against a real lockstep server in the test world with one wall (test_gym.py's): a step at 0.5 m/s
moves the ground truth 0.05 m, as the drive's ramp and the stepper's midpoint integration give it;
driving into the wall ends the episode with a collision, the chassis stopped at the wall's face
(the stepper takes back a step that would sink it in); a seed draws the same first observation
twice.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from test_gym import FAST, WALL_WORLD, WALL_X, drive, ground_truth, make, unwrapped

import simbot.gym
from simbot.sim.physics.kinematic_world import KINEMATIC_STEP_S


@pytest.fixture(scope="module")
def kinematic(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    world = tmp_path_factory.mktemp("gym") / "walled.sdf"
    world.write_text(WALL_WORLD)
    env = make(simbot.gym.NAVIGATE, **{**FAST, "world": str(world), "physics": "kinematic"})
    yield env
    env.close()


def test_an_env_step_is_a_control_period_of_kinematic_steps(kinematic: Any) -> None:
    _, info = kinematic.reset(options={"start": (0.0, 0.0, 0.0), "goal": (-3.0, 0.0, 0.0)})
    assert unwrapped(kinematic).physics_steps == round(0.1 / KINEMATIC_STEP_S) == 20
    start = info["sim_time"]
    *_, info = drive(kinematic, 0.0)
    assert info["sim_time"] == pytest.approx(start + 0.1, abs=1e-9)


def test_a_step_of_0_1_s_at_0_5_m_s_moves_the_robot_0_05_m(kinematic: Any) -> None:
    """Up to speed after a second, one more step moves the ground truth 0.05 m straight ahead (the
    command is the base's velocity: no slip, so 1 mm of slack rather than the dynamic test's 3)."""
    kinematic.reset(options={"start": (0.0, 0.0, 0.0), "goal": (-3.0, 0.0, 0.0)})
    for _ in range(10):
        obs, *_ = drive(kinematic, 0.5)
    before = ground_truth(kinematic)
    obs, _, terminated, _, info = drive(kinematic, 0.5)
    after = ground_truth(kinematic)
    assert after[0] - before[0] == pytest.approx(0.05, abs=0.001)
    assert abs(after[1] - before[1]) < 1e-6 and abs(after[2]) < 1e-6
    assert obs["twist"][0] == pytest.approx(0.5, abs=0.01)
    assert not terminated and info["collisions"] == 0


def test_driving_into_the_wall_ends_the_episode_with_a_collision(kinematic: Any) -> None:
    kinematic.reset(options={"start": (0.0, 0.0, 0.0), "goal": (-3.0, 0.0, 0.0)})
    for _ in range(40):
        obs, reward, terminated, truncated, info = drive(kinematic, 1.0)
        if terminated or truncated:
            break
    assert terminated and info["success"] is False and info["collisions"] == 1, info
    assert any(name.startswith("wall::") for name in info["touched"]), info["touched"]
    assert reward < -9.0  # the collision penalty (10)
    front = ground_truth(kinematic)[0] + unwrapped(kinematic).robot.footprint.xmax
    assert front == pytest.approx(WALL_X - 0.1, abs=0.01)  # at 1 m/s a 5 ms step moves 5 mm


def test_the_same_seed_draws_the_same_first_observation(kinematic: Any) -> None:
    first, _ = kinematic.reset(seed=5)
    drive(kinematic, 0.8, 0.5)
    again, _ = kinematic.reset(seed=5)
    assert all(first[key].tobytes() == again[key].tobytes() for key in first)
