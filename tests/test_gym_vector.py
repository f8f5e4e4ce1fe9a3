"""Learning at scale (issue 47, items 2 and 3): the world off the bus, and native vector envs.

- An env that no one watches steps its world in its own process (simbot.gym.local); its
  observations, rewards and contacts equal, byte for byte, those of the same env on a lockstep
  server (`watch=True`), for the same seed and actions: kinematic in the warehouse with its
  people (the lidars see their legs), dynamic, and with a camera.
- `make_vec(..., vectorization_mode="vector_entry_point")`: sub-env i, seeded S + i, gives the
  single env's episode with that seed, through Gymnasium 1.x's next-step autoreset, in this process
  and in two simulation processes; Dock too, with a camera (its frames rendered off the bus).
- Bad input is one line naming it; a simulation process that dies is a SimServerError naming its
  envs, with nothing left running; a parent killed with SIGKILL leaves no simulation process.
"""

from __future__ import annotations

import json
import os
import signal
from typing import Any

import gymnasium
import numpy as np
import pytest
from server_helpers import alive, killed_script, wait_until
from test_gym import WALL_WORLD

from simbot.gym import EnvConfigError, SimServerError
from simbot.gym.base import SimbotEnv
from simbot.gym.local import LocalSession
from simbot.gym.session import Session
from simbot.gym.vector import SimbotVectorEnv

KINEMATIC_PEOPLE: dict[str, Any] = {"world": "warehouse", "people": True, "physics": "kinematic"}
DYNAMIC_EMPTY: dict[str, Any] = {"world": "empty", "max_linear": 1.0, "max_angular": 1.0}
CAMERA: dict[str, Any] = {
    "world": "warehouse",
    "physics": "kinematic",
    "cameras": ("camera_front",),
    "camera_size": (32, 24),
}
"""A camera off the bus: its render worker started from this process (pytest's main module is guarded)."""


def actions(step: int, env: int = 0) -> np.ndarray:
    """A drive that turns back and forth, different per env."""
    return np.array([0.8, 0.6 * np.sin(step / 4 + env)], np.float32)


def run_single(env: Any, seed: int, steps: int, index: int = 0, same_step: bool = False) -> list[tuple[Any, ...]]:
    """The single env's episode(s) from `reset(seed)`, reset with no seed after each ends (as the
    vector env's autoreset does): (obs, reward, terminated, truncated) per step. Next-step: the
    step after an end is the reset, reward 0; same-step: the reset's observation replaces the
    last one, which is kept as the record's fifth item."""
    obs, _ = env.reset(seed=seed)
    record: list[tuple[Any, ...]] = [(obs, 0.0, False, False)]
    ended = False
    for step in range(steps):
        if ended:
            obs, _ = env.reset()
            record.append((obs, 0.0, False, False))
            ended = False
            continue
        obs, reward, terminated, truncated, _ = env.step(actions(step, index))
        ended = terminated or truncated
        if same_step and ended:
            final, (obs, _), ended = obs, env.reset(), False
            record.append((obs, float(reward), bool(terminated), bool(truncated), final))
            continue
        record.append((obs, float(reward), bool(terminated), bool(truncated)))
    return record


def assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray], what: str) -> None:
    assert a.keys() == b.keys(), what
    for key in a:
        assert a[key].dtype == b[key].dtype and np.array_equal(a[key], b[key]), f"{what}: {key} differs"


@pytest.fixture(scope="module")
def walled(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The test world with a wall 2.4 m ahead of the origin, kinematic, short episodes: collisions
    and time limits end episodes within the run."""
    world = tmp_path_factory.mktemp("vector") / "walled.sdf"
    world.write_text(WALL_WORLD)
    return {"world": str(world), "physics": "kinematic", "max_episode_steps": 12, "max_linear": 1.0}


# --- the world off the bus --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs", [KINEMATIC_PEOPLE, DYNAMIC_EMPTY, CAMERA], ids=["kinematic-people", "dynamic", "camera"]
)
def test_the_world_off_the_bus_observes_exactly_what_the_bus_path_observes(kwargs: dict[str, Any]) -> None:
    local = gymnasium.make("simbot/Navigate-v0", cameras_in_process=bool(kwargs.get("cameras")), **kwargs)
    watched = gymnasium.make("simbot/Navigate-v0", watch=True, **kwargs)
    try:
        runs = [run_single(env, 11, 25) for env in (local, watched)]
        local_env, watched_env = local.unwrapped, watched.unwrapped
        assert isinstance(local_env, SimbotEnv) and isinstance(watched_env, SimbotEnv)
        assert isinstance(local_env.session, LocalSession) and local_env.session.process is None
        assert isinstance(watched_env.session, Session) and watched_env.session.process is not None
    finally:
        local.close()
        watched.close()
    moved = np.hypot(*runs[0][-1][0]["goal"][:2] - runs[0][0][0]["goal"][:2])
    assert moved > 0.5, "the robot should have moved relative to its goal"
    for step, (a, b) in enumerate(zip(*runs, strict=True)):
        assert_same(a[0], b[0], f"step {step}")
        assert a[1:] == b[1:], f"step {step}: reward and ends {a[1:]} vs {b[1:]}"


# --- native vector envs ---------------------------------------------------------------------------


@pytest.mark.parametrize("processes", [0, 2])
def test_each_sub_env_is_the_single_env_with_its_seed_through_autoreset(walled: dict[str, Any], processes: int) -> None:
    steps, seed, count = 30, 5, 3
    envs = gymnasium.make_vec(
        "simbot/Navigate-v0", num_envs=count, vectorization_mode="vector_entry_point", processes=processes, **walled
    )
    try:
        assert isinstance(envs, SimbotVectorEnv) and envs.processes == processes
        assert envs.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
        vector = run_vector(envs, seed, steps)
    finally:
        envs.close()
    for i, expected in enumerate(assert_each_is_the_single_env(vector, seed, steps, walled)):
        ends = sum(1 for record in expected if record[2] or record[3])
        assert ends >= 1, f"env {i}: no episode ended in {steps} steps; autoreset untested"


def run_vector(envs: Any, seed: int, steps: int) -> list[list[tuple[Any, ...]]]:
    """Each sub-env's records from `reset(seed)` (as `run_single` keeps them), the vector env
    autoresetting: (obs, reward, terminated, truncated) per step."""
    count = envs.num_envs
    obs, _ = envs.reset(seed=seed)
    vector: list[list[tuple[Any, ...]]] = [
        [({k: v[i] for k, v in obs.items()}, 0.0, False, False)] for i in range(count)
    ]
    for step in range(steps):
        obs, rewards, terminated, truncated, _ = envs.step(np.stack([actions(step, i) for i in range(count)]))
        for i in range(count):
            vector[i].append(
                ({k: v[i] for k, v in obs.items()}, float(rewards[i]), bool(terminated[i]), bool(truncated[i]))
            )
    return vector


def assert_each_is_the_single_env(
    vector: list[list[tuple[Any, ...]]], seed: int, steps: int, kwargs: dict[str, Any]
) -> list[list[tuple[Any, ...]]]:
    """Sub-env i's records equal the single env's from seed + i, step for step; the single env's records."""
    single = gymnasium.make("simbot/Navigate-v0", **kwargs)
    episodes = []
    try:
        for i, records in enumerate(vector):
            expected = run_single(single, seed + i, steps, i)
            for step, (a, b) in enumerate(zip(records, expected, strict=True)):
                assert_same(a[0], b[0], f"env {i} step {step}")
                assert a[1:] == b[1:], f"env {i} step {step}: {a[1:]} vs {b[1:]}"
            episodes.append(expected)
    finally:
        single.close()
    return episodes


def test_sub_envs_among_people_are_the_single_env_though_their_people_think_together() -> None:
    """The warehouse with its people: the sub-envs' worlds step together (each world's people in the
    same pass of the crowd's arrays, seeing only their own world), and each sub-env still gives the
    single env's episode for its seed."""
    steps, seed, count = 8, 21, 2
    envs = gymnasium.make_vec(
        "simbot/Navigate-v0", num_envs=count, vectorization_mode="vector_entry_point", processes=0, **KINEMATIC_PEOPLE
    )
    try:
        vector = run_vector(envs, seed, steps)
    finally:
        envs.close()
    assert_each_is_the_single_env(vector, seed, steps, KINEMATIC_PEOPLE)


def test_same_step_autoreset_gives_the_final_observation_in_the_info(walled: dict[str, Any]) -> None:
    """`autoreset_mode="SameStep"` (what Stable-Baselines3 runs on): the step that ends an episode
    returns the next episode's first observation, the last one in `info["final_obs"]`."""
    steps, seed = 30, 5
    envs = gymnasium.make_vec(
        "simbot/Navigate-v0", num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="SameStep", **walled
    )
    single = gymnasium.make("simbot/Navigate-v0", **walled)
    try:
        expected = run_single(single, seed, steps, same_step=True)
        obs, _ = envs.reset(seed=seed)
        assert_same({k: v[0] for k, v in obs.items()}, expected[0][0], "reset")
        finals = 0
        for step in range(steps):
            obs, rewards, terminated, truncated, info = envs.step(actions(step)[None])
            want = expected[step + 1]
            assert_same({k: v[0] for k, v in obs.items()}, want[0], f"step {step}")
            assert (float(rewards[0]), bool(terminated[0]), bool(truncated[0])) == want[1:4], f"step {step}"
            if len(want) == 5:
                finals += 1
                assert info["_final_obs"][0]
                assert_same(info["final_obs"][0], want[4], f"step {step}: final")  # an object array, as Gymnasium's own
        assert finals >= 1, "no episode ended: the same-step reset went untested"
    finally:
        envs.close()
        single.close()


def test_goal_ahead_puts_the_goal_straight_ahead_at_the_starts_heading() -> None:
    env = gymnasium.make(
        "simbot/Navigate-v0", world="empty", physics="kinematic", goal_distance=(2.0, 2.0), goal_ahead=True
    )
    try:
        for seed in range(5):
            obs, info = env.reset(seed=seed)
            assert obs["goal"] == pytest.approx([2.0, 0.0, 0.0], abs=0.01), f"seed {seed}: {obs['goal']}"
            assert info["distance"] == pytest.approx(2.0, abs=0.01)
    finally:
        env.close()


def test_dock_batches_too_with_a_camera_and_its_sub_envs_are_the_single_env() -> None:
    """Each sub-env's render worker started by its simulation process, the frames taken back."""
    kwargs: dict[str, Any] = {"world": "empty", "cameras": ("camera_front",), "camera_size": (32, 24)}
    envs = gymnasium.make_vec("simbot/Dock-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    single = gymnasium.make("simbot/Dock-v0", cameras_in_process=True, **kwargs)
    try:
        assert isinstance(envs, SimbotVectorEnv) and envs.action_space.shape == (2, 3)
        obs, _ = envs.reset(seed=[8, 9])
        image = obs["camera_front"]
        assert image.shape == (2, 24, 32, 3) and 100 < image.mean() < 250, "not the lit floor (an empty buffer?)"
        step = envs.step(np.tile(np.array([0.3, 0.0, 0.0], np.float32), (2, 1)))
        for i, seed in enumerate((8, 9)):
            first, _ = single.reset(seed=seed)
            assert_same({k: v[i] for k, v in obs.items()}, first, f"env {i} reset")
            after = single.step(np.array([0.3, 0.0, 0.0], np.float32))
            assert_same({k: v[i] for k, v in step[0].items()}, after[0], f"env {i} step")
            assert float(step[1][i]) == float(after[1])
    finally:
        envs.close()
        single.close()


# --- bad input and failures --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"num_envs": 0}, "num_envs 0: must be a whole number ≥ 1"),
        ({"num_envs": -2}, "num_envs -2"),
        ({"num_envs": 2, "processes": 3}, "processes 3: must be a whole number from 0"),
        ({"num_envs": 2, "processes": 0, "cameras": ("camera_front",)}, "cameras camera_front with processes=0"),
        ({"num_envs": 2, "watch": True}, "watch=True needs a server"),
        ({"num_envs": 2, "physics": "warp"}, "physics 'warp': one of dynamic, kinematic"),
        ({"num_envs": 10**6}, "num_envs 1000000: about 4"),
        ({"num_envs": 2, "autoreset_mode": "later"}, "autoreset_mode 'later': one of NextStep, SameStep"),
    ],
)
def test_bad_vector_input_is_one_line_naming_it(kwargs: dict[str, Any], named: str) -> None:
    with pytest.raises(EnvConfigError) as raised:
        gymnasium.make_vec("simbot/Navigate-v0", vectorization_mode="vector_entry_point", world="empty", **kwargs)
    assert named in str(raised.value) and "\n" not in str(raised.value)


def test_a_dead_simulation_process_is_an_error_naming_its_envs_and_nothing_is_left_running() -> None:
    envs = gymnasium.make_vec(
        "simbot/Navigate-v0", num_envs=3, vectorization_mode="vector_entry_point", processes=2, world="empty"
    )
    pids = {group.process.pid for group in envs._groups}  # type: ignore[attr-defined]
    try:
        envs.reset(seed=1)
        os.kill(envs._groups[1].process.pid, signal.SIGKILL)  # type: ignore[attr-defined]
        with pytest.raises(SimServerError, match=r"simulation process of envs 2 \(pid \d+\) exited with code -9"):
            envs.step(np.zeros((3, 2), np.float32))
        assert alive(pids) == set(), f"left running: {alive(pids)}"
    finally:
        envs.close()


def test_a_parent_killed_with_sigkill_leaves_no_simulation_process() -> None:
    code = (
        "import json, os, signal, gymnasium, simbot.gym\n"
        "envs = gymnasium.make_vec('simbot/Navigate-v0', num_envs=2, vectorization_mode='vector_entry_point', "
        "processes=2, world='empty')\n"
        "envs.reset(seed=0)\n"
        "print(json.dumps([g.process.pid for g in envs._groups]), flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    pids = set(json.loads(killed_script(code)))
    assert len(pids) == 2
    wait_until(lambda: not alive(pids), 60.0, f"simulation processes {sorted(pids)} to end")
