"""Many environments at once: Gymnasium's vector envs (sync and async) over simbot's environment,
episodes across Ray actors (`simbot.gym.ray.run_episodes`), the `simbot experiment` command, and
the built-in policies.

The vector envs here are told to `watch`, so that each starts its own lockstep server, and closing
must leave none running (the servers this process started, found through /proc); the Ray actors'
envs step their worlds in their own processes, off the bus (simbot.gym.local). Ray starts once for
the module (seconds on two cores), with two CPUs, no dashboard and the actors' logs in its files.
The episodes run on the easy variant: the empty world, the goal 2 m away, a short time limit.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from server_helpers import alive, descendants

gymnasium = pytest.importorskip("gymnasium")
ray = pytest.importorskip("ray")

import simbot.gym  # noqa: E402,F401  registers the environments
from simbot.gym import experiment  # noqa: E402
from simbot.gym.policies import PolicyError, RandomPolicy, ScriptedPolicy, make_policy  # noqa: E402
from simbot.gym.ray import COLUMNS, EpisodeResult, ExperimentError, run_episodes  # noqa: E402

ENV_ID = "simbot/Navigate-v0"
EASY: dict[str, Any] = {"world": "empty", "goal_distance": (2.0, 2.0), "max_episode_steps": 120}
"""The easy variant: nothing in the way, the goal 2 m off in a direction and with a heading the
seed draws; the scripted policy turns, drives and turns again in well under 120 steps."""
EPISODES, ACTORS, SEED = 4, 2, 100
SERVER = b"simbot.sim.server"
VECTOR_KWARGS: dict[str, dict[str, Any]] = {"sync": {}, "async": {"context": "spawn"}}
"""Async workers spawned, as docs/learning.md says for a process whose Zenoh threads run already:
this test process has reset envs before (the sync case, the Ray driver), and a worker forked from
it would hang opening its session."""


# --------------------------------------------------------------------------- processes


def servers_below(pid: int) -> set[int]:
    """The simbot servers (`python -m simbot.sim.server ...`, not the keeper that starts one) among
    `pid`'s descendants that are still running."""
    servers = set()
    for child in descendants(pid):
        try:
            argv = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if argv[1:3] == [b"-m", SERVER]:
            servers.add(child)
    return alive(servers)


# --------------------------------------------------------------------------- vector envs


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_a_vector_env_steps_two_servers_and_closes_them(mode: str) -> None:
    """`make_vec` with two envs: each its own server (two servers run), seeded resets, steps whose
    observations each lie in the single env's space, and after `close` no server left."""
    before = servers_below(os.getpid())
    kwargs = {**EASY, "watch": True}
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, vectorization_mode=mode, vector_kwargs=VECTOR_KWARGS[mode], **kwargs)
    try:
        obs, _info = envs.reset(seed=[1, 2])
        started = servers_below(os.getpid()) - before
        assert len(started) == 2, f"{mode}: expected one server per env, found {started}"
        for _ in range(3):
            obs, rewards, terminated, truncated, info = envs.step(np.tile([0.3, 0.1], (2, 1)).astype(np.float32))
        assert rewards.shape == terminated.shape == truncated.shape == (2,)
        for index in range(2):
            single = {key: value[index] for key, value in obs.items()}
            assert envs.single_observation_space.contains(single), f"{mode}: env {index}'s observation"
            assert np.all(np.isfinite(single["goal"])) and single["scan"].size > 0
        assert not np.allclose(obs["goal"][0], obs["goal"][1]), "two seeds gave the same goal"
    finally:
        envs.close()
    assert alive(started) == set(), f"{mode}: servers left running after close: {alive(started)}"


# --------------------------------------------------------------------------- policies, no server


def test_the_scripted_policy_aims_drives_detours_and_turns_to_the_goal_heading() -> None:
    policy = ScriptedPolicy(max_speed=1.0, max_turn=1.0)
    clear = np.full(360, 10.0)
    v, w = policy({"goal": np.array([2.0, 0.0, 0.0]), "scan": clear})
    assert v > 0.5 and w == pytest.approx(0.0), "goal straight ahead: drive, no turn"
    v, w = policy({"goal": np.array([0.0, 2.0, 0.0]), "scan": clear})
    assert v == pytest.approx(0.0, abs=1e-6) and w > 0.5, "goal to the left: turn left, no speed"
    blocked = clear.copy()
    blocked[175:185] = 0.9  # bins around 0 rad: something 0.9 m ahead
    blocked[90] = 0.5  # and something on the right (−90°): turn left
    v, w = policy({"goal": np.array([5.0, 0.0, 0.0]), "scan": blocked})
    assert v == 0.0 and w == 1.0, "obstacle ahead nearer than the goal: turn in place, to the freer side"
    v, w = policy({"goal": np.array([5.0, 0.5, 0.0]), "scan": clear})
    assert v == policy.min_speed and w == 0.0, "then a detour: straight on, not back into the obstacle"
    policy.reset(0)
    v, w = policy({"goal": np.array([0.05, 0.0, 1.0]), "scan": clear})
    assert v == 0.0 and w > 0.5, "at the goal: turn in place to its heading"
    assert tuple(policy({"goal": np.array([0.05, 0.0, 0.0]), "scan": clear})) == (0.0, 0.0), "arrived: stop"


def test_the_random_policy_repeats_with_its_seed_and_stays_in_bounds() -> None:
    space = gymnasium.spaces.Box(np.array([-0.5, -1.0], np.float32), np.array([1.0, 1.0], np.float32))
    policy = make_policy("random", space)
    assert isinstance(policy, RandomPolicy)
    policy.reset(7)
    first = [policy({}) for _ in range(5)]
    policy.reset(7)
    assert all(np.array_equal(a, b) for a, b in zip(first, (policy({}) for _ in range(5))))
    assert all(space.contains(action) for action in first)


@pytest.mark.parametrize("name", ["nope", "no_such_module_xyz:policy", "math:no_such_function", "math:pi"])
def test_a_policy_that_names_nothing_is_a_policy_error(name: str) -> None:
    with pytest.raises(PolicyError):
        make_policy(name, None)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--env", "simbot/Nowhere-v0", "--policy", "random"], "unknown environment"),
        (["--policy", "teleport"], "unknown policy"),
        (["--policy", "no_such_module_xyz:act"], "cannot import"),
        (["--policy", "random", "--episodes", "0"], "expected a whole number ≥ 1"),
        (["--policy", "random", "--world", "atlantis"], "atlantis"),
        (["--policy", "random", "--address", "auto", "--num-cpus", "2"], "not allowed with"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_before_ray_starts(
    args: list[str], says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert experiment.main([*args, "-o", str(tmp_path / "results.csv")]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "results.csv").exists()


def test_run_episodes_refuses_no_episodes() -> None:
    with pytest.raises(ExperimentError):
        run_episodes(ENV_ID, "random", episodes=0)


# --------------------------------------------------------------------------- Ray


@pytest.fixture(scope="module")
def ray_session() -> Iterator[None]:
    """One local Ray for the module: two CPUs, no dashboard, the actors' output in Ray's files;
    shut down at the end, and no server of an actor left behind."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="WARNING")
    try:
        yield
        assert servers_below(os.getpid()) == set(), "a Ray actor's server outlived its experiment"
    finally:
        ray.shutdown()


@pytest.fixture(scope="module")
def scripted(ray_session: None) -> list[EpisodeResult]:
    return run_episodes(ENV_ID, "scripted", EPISODES, ACTORS, SEED, EASY)


def test_episodes_across_actors_have_a_row_each_with_distinct_seeds(scripted: list[EpisodeResult]) -> None:
    assert [r.episode for r in scripted] == list(range(EPISODES))
    assert len({r.seed for r in scripted}) == EPISODES
    for result in scripted:
        assert 1 <= result.steps <= EASY["max_episode_steps"] and math.isfinite(result.episode_return)
        assert result.collisions >= 0 and result.clipped_actions == 0, "the scripted policy stays in the action space"


def test_the_same_seeds_give_the_same_results(scripted: list[EpisodeResult]) -> None:
    """Episode i has seed SEED + i whichever actor runs it, and the env's reset with it fixes the
    episode: a second experiment is the first, to the last bit of every return."""
    assert run_episodes(ENV_ID, "scripted", EPISODES, ACTORS, SEED, EASY) == scripted


def test_the_scripted_policy_succeeds_at_least_as_often_as_the_random_one(
    scripted: list[EpisodeResult], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The random policy through the command line, in the module's Ray session: its CSV has a row
    per episode under the documented columns, and its success rate is no better than scripted's."""
    out = tmp_path / "random.csv"
    extra = ["--env-arg=goal_distance=[2.0, 2.0]", f"--max-episode-steps={EASY['max_episode_steps']}"]
    argv = ["--env", ENV_ID, "--policy", "random", "--episodes", str(EPISODES), "--actors", str(ACTORS)]
    assert experiment.main([*argv, "--seed", str(SEED), "--world", EASY["world"], *extra, "-o", str(out)]) == 0
    summary = capsys.readouterr().out.strip().splitlines()
    assert len(summary) == 1 and "success" in summary[0], summary
    with out.open(newline="") as file:
        rows = list(csv.DictReader(file))
    assert tuple(rows[0]) == COLUMNS and [int(r["seed"]) for r in rows] == [SEED + i for i in range(EPISODES)]
    random_rate = sum(r["success"] == "True" for r in rows) / len(rows)
    scripted_rate = sum(r.success for r in scripted) / len(scripted)
    assert scripted_rate >= random_rate, f"scripted {scripted_rate:.0%} < random {random_rate:.0%}"
    assert scripted_rate > 0, f"the scripted policy never reached a goal 2 m ahead in the empty world: {scripted}"


def test_an_option_the_environment_refuses_is_one_line_and_exit_2_from_the_actors(
    ray_session: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Options only the environment knows are checked where it is made, in the actors; its one-line
    EnvConfigError comes back as the command's, not as Ray's actor-death traceback."""
    argv = ["--policy", "scripted", "--episodes", "2", "--actors", "2", "--world", "empty"]
    assert experiment.main([*argv, "--env-arg", "goal_distance=[3, 1]", "-o", str(tmp_path / "r.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "goal_distance" in err[0], err


def test_simbot_runs_experiment_with_the_rest_of_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from simbot import cli

    assert cli.main(["experiment", "--policy", "teleport", "-o", str(tmp_path / "r.csv")]) == 2
    assert capsys.readouterr().err.startswith("simbot experiment: error: unknown policy 'teleport'")
