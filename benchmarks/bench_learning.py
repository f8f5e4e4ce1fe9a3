"""Benchmark of learning on simbot's environments: PPO on native vector envs, against the random policy.

One run, one machine, so the comparison holds where the machine is shared:

1. Stable-Baselines3's own env checker (`stable_baselines3.common.env_checker.check_env`) on
   `simbot/Navigate-v0` and `simbot/Dock-v0` (empty world): pass or fail, and its warnings;
2. the baseline: env steps per second of the random policy on one env on a server (`watch=True`,
   dynamic physics: the path the 533 s PPO run of 2026-11-27 trained on), and on the native vector
   env PPO trains on, in the same run;
3. PPO (`MultiInputPolicy` on the Dict observation, on the CPU, torch on one thread, observations
   and rewards normalised by `VecNormalize`, seeded) trained on the easy variant for a fixed budget
   of env steps (`--steps`) on a native vector env (`simbot.gym.sb3`: `--envs` sub-envs in one
   simulation process per core, kinematic physics, off the bus);
4. the trained policy (deterministic: the Gaussian's mean) and `simbot.gym.policies.RandomPolicy`
   over the same `--episodes` seeded episodes of the same variant: success rates, mean returns
   (the environment's reward, not normalised), their ratio, mean episode lengths.

The easy variant is `simbot/Navigate-v0` in the empty world, kinematic, with (v, ω) bounded to
1 m/s and 1 rad/s, 60 steps of 0.1 s an episode, the start anywhere free and the goal 2 m straight
ahead of it at its heading (`goal_ahead=True`).

`--long` instead trains PPO for `--long-steps` (1 M) env steps on kinematic Navigate-v0 in the
warehouse with its people (the default task: goals 1–5 m away, any heading, 500 steps; (v, ω)
within 1 m/s and 1 rad/s), records
the success rate of the training episodes after each rollout, and writes the curve as
docs/learning-curve.svg and its table into docs/learning.md. `make bench-learning` runs both;
it needs the `learning` extra, which it installs.

    python benchmarks/bench_learning.py [--steps N] [--envs N] [--episodes N] [--seed S] [--eval-seed S]
    python benchmarks/bench_learning.py --long [--long-steps N] [--envs N]
"""

from __future__ import annotations

import argparse
import re
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, NoReturn

import gymnasium
import numpy as np
from svg_chart import line_chart
from tables import cpu_model, publish

import simbot.gym  # noqa: F401  registers simbot/Navigate-v0 and simbot/Dock-v0
from simbot.gym.policies import RandomPolicy

ENVIRONMENTS = ("simbot/Navigate-v0", "simbot/Dock-v0")
ENV_ID = "simbot/Navigate-v0"
EASY: dict[str, Any] = {
    "world": "empty",
    "physics": "kinematic",
    "control_period": 0.1,
    "max_linear": 1.0,
    "max_angular": 1.0,
    "max_episode_steps": 60,
    "goal_distance": (2.0, 2.0),
    "goal_ahead": True,
}
"""Navigate-v0's keywords for the easy variant."""
NAVIGATE_ONLY = ("goal_distance", "goal_ahead")
"""Of those, the ones Dock-v0 does not take (its checker runs with the rest)."""
LONG: dict[str, Any] = {
    "world": "warehouse",
    "people": True,
    "physics": "kinematic",
    "max_linear": 1.0,
    "max_angular": 1.0,
}
"""The long run's task: Navigate-v0's defaults in the warehouse with its people, kinematic, (v, ω)
within 1 m/s and 1 rad/s (the drive's own 7.5 m/s and 37.5 rad/s leave a Gaussian policy crashing)."""
PPO_SETTINGS: dict[str, Any] = {"batch_size": 64, "n_epochs": 10, "learning_rate": 3e-4, "gamma": 0.99}
ROLLOUT = 256
"""Env steps per PPO rollout, all envs together (each env's `n_steps` is this ÷ envs): the one-env
run's rollout, so that a budget makes as many updates (40 at the default)."""
DEFAULT_STEPS = 10_240
DEFAULT_ENVS = 4
LONG_STEPS = 1_000_000
LONG_ROLLOUT = 2048
BASELINE_STEPS = 200
ROOT = Path(__file__).resolve().parents[1]
LEARNING_PAGE = ROOT / "docs" / "learning.md"
CURVE = ROOT / "docs" / "learning-curve.svg"


class _Parser(argparse.ArgumentParser):
    """A bad argument is one line and exit 2, no usage block."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def at_least(low: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected at least {low}, got {value}")
        return value

    return parse


def make_easy() -> gymnasium.Env[Any, Any]:
    return gymnasium.make(ENV_ID, **EASY)


def check_envs() -> list[str]:
    """Rows: Stable-Baselines3's check_env on each environment, pass or fail, with its warnings."""
    from stable_baselines3.common.env_checker import check_env

    rows = []
    for env_id in ENVIRONMENTS:
        common = {k: v for k, v in EASY.items() if k not in NAVIGATE_ONLY}
        env = gymnasium.make(env_id, **(EASY if env_id == ENV_ID else common))
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                check_env(env, warn=True)
            said = sorted({first_sentence(str(w.message)) for w in caught})
            result = "pass" + (f" ({len(said)} warning(s): {'; '.join(said)})" if said else ", no warnings")
        except Exception as exc:  # the checker's verdict is an exception of any kind
            result = f"FAIL: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        finally:
            env.close()
        rows.append(f"| Stable-Baselines3 `check_env`, `{env_id}` (empty world) | {result.replace('|', '/')} |")
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


@dataclass
class Training:
    model: Any
    normalizer: Any
    """The VecNormalize the policy was trained behind: its observation statistics, frozen, feed the evaluation."""
    wall_s: float
    steps: int
    episodes: int
    successes: int
    curve: list[tuple[int, float, float]] = field(default_factory=list)
    """(env steps, wall seconds, success rate of the training episodes that ended in that rollout)."""


def train(kwargs: dict[str, Any], steps: int, envs: int, rollout: int, seed: int) -> Training:
    """PPO on `kwargs`'s Navigate-v0 for `steps` env steps on a native vector env of `envs`, seeded, on the CPU."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from simbot.gym.sb3 import vec_env

    torch.set_num_threads(1)  # the simulation processes have the cores: a second thread would only queue

    class Progress(BaseCallback):
        """Counts the training episodes and their successes, each rollout's success rate on the curve."""

        def __init__(self) -> None:
            super().__init__()
            self.episodes = self.successes = 0
            self.rollout_episodes = self.rollout_successes = 0
            self.curve: list[tuple[int, float, float]] = []
            self.started = time.perf_counter()

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    self.episodes += 1
                    self.rollout_episodes += 1
                    reached = bool(info.get("success"))
                    self.successes += reached
                    self.rollout_successes += reached
            return True

        def _on_rollout_end(self) -> None:
            elapsed = time.perf_counter() - self.started
            if self.rollout_episodes:
                self.curve.append((self.num_timesteps, elapsed, self.rollout_successes / self.rollout_episodes))
            print(
                f"  {self.num_timesteps} steps, {elapsed:.0f} s, {self.num_timesteps / elapsed:.1f} steps/s, "
                f"{self.episodes} episodes, {self.successes} reached the goal",
                file=sys.stderr,
                flush=True,
            )
            self.rollout_episodes = self.rollout_successes = 0

    vector = VecNormalize(VecMonitor(vec_env(ENV_ID, envs, **kwargs)), norm_obs=True, norm_reward=True)
    try:
        vector.seed(seed)
        model = PPO(
            "MultiInputPolicy",
            vector,
            n_steps=rollout // envs,
            seed=seed,
            device="cpu",
            verbose=0,
            **PPO_SETTINGS,
        )
        progress = Progress()
        started = time.perf_counter()
        model.learn(total_timesteps=steps, callback=progress)
        wall = time.perf_counter() - started
        vector.training = False
        steps_done = int(model.num_timesteps)
        return Training(model, vector, wall, steps_done, progress.episodes, progress.successes, progress.curve)
    finally:
        vector.close()


def random_rate(make: Callable[[], gymnasium.Env[Any, Any]], steps: int) -> float:
    """Env steps per second of the random policy on the env `make` makes (start-up not counted)."""
    env = make()
    try:
        policy = RandomPolicy.for_space(env.action_space)
        obs, _ = env.reset(seed=0)
        started = time.perf_counter()
        for _ in range(steps):
            obs, _, terminated, truncated, _ = env.step(policy(obs))
            if terminated or truncated:
                obs, _ = env.reset()
        return steps / (time.perf_counter() - started)
    finally:
        env.close()


@dataclass
class Episodes:
    successes: int
    returns: list[float]
    lengths: list[int]
    wall_s: float

    @property
    def rate(self) -> float:
        return self.successes / len(self.returns)


def evaluate(
    env: gymnasium.Env[Any, Any], act: Callable[[Any], Any], seeds: Sequence[int], reset: Any = None
) -> Episodes:
    """Episodes of `env`, one per seed, actions from `act(obs)`; `reset(seed)` first where given."""
    successes, returns, lengths = 0, [], []
    started = time.perf_counter()
    for seed in seeds:
        if reset is not None:
            reset(seed)
        obs, info = env.reset(seed=seed)
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(act(obs))
            total, steps, done = total + float(reward), steps + 1, terminated or truncated
        successes += bool(info["success"])
        returns.append(total)
        lengths.append(steps)
    return Episodes(successes, returns, lengths, time.perf_counter() - started)


def ratio(a: float, b: float) -> str:
    """a ÷ b where b > 0; else what can be said (a rate of 0, a return of 0 or below has no ratio)."""
    if b > 0:
        return f"{a / b:.2f}"
    if b == 0:
        return "∞ (random: 0)" if a > 0 else "— (both 0)"
    return f"— (random's below 0; PPO − random: {a - b:+.2f})"


def first_sentence(message: str) -> str:
    """A warning's first sentence, without its links."""
    return re.split(r"\.\s|\s+cf\b|\s+https?://", message.strip(), maxsplit=1)[0].rstrip(".")


def results(args: argparse.Namespace) -> list[str]:
    checks = check_envs()
    server_rate = random_rate(lambda: gymnasium.make(ENV_ID, **{**EASY, "physics": "dynamic", "watch": True}), 200)
    native_rate = vector_random_rate(EASY, args.envs, 4 * BASELINE_STEPS)
    print(f"training PPO for {args.steps} env steps ...", file=sys.stderr, flush=True)
    trained = train(EASY, args.steps, args.envs, ROLLOUT, args.seed)
    seeds = list(range(args.eval_seed, args.eval_seed + args.episodes))
    env = make_easy()
    try:
        normalizer, model = trained.normalizer, trained.model
        ppo = evaluate(env, lambda obs: model.predict(normalizer.normalize_obs(obs), deterministic=True)[0], seeds)
        random = RandomPolicy.for_space(env.action_space)
        chance = evaluate(env, random, seeds, reset=random.reset)
    finally:
        env.close()
    n = args.episodes
    mean_ppo, mean_random = float(np.mean(ppo.returns)), float(np.mean(chance.returns))
    training_rate = trained.steps / trained.wall_s
    variant = (
        f"`{ENV_ID}`, empty world, kinematic, the goal {EASY['goal_distance'][0]:g} m straight ahead of a free start "
        f"at its heading, (v, ω) within 1 m/s and 1 rad/s, {EASY['max_episode_steps']} steps of 0.1 s"
    )
    return [
        f"Easy variant: {variant}. {n} evaluation episodes, seeds {seeds[0]}–{seeds[-1]}, the same for both policies.",
        "",
        "| over the same episodes | PPO, trained (deterministic) | random policy | PPO ÷ random |",
        "| --- | --- | --- | --- |",
        f"| success rate | {ppo.successes}/{n} ({100 * ppo.rate:.0f} %) | {chance.successes}/{n} "
        f"({100 * chance.rate:.0f} %) | {ratio(ppo.rate, chance.rate)} |",
        f"| mean return | {mean_ppo:.2f} | {mean_random:.2f} | {ratio(mean_ppo, mean_random)} |",
        f"| mean steps an episode | {np.mean(ppo.lengths):.1f} | {np.mean(chance.lengths):.1f} | "
        f"{np.mean(ppo.lengths) / np.mean(chance.lengths):.2f} |",
        "",
        "| training and checks | |",
        "| --- | --- |",
        f"| budget | {args.steps} env steps (PPO `MultiInputPolicy`, `VecNormalize`, native vector env of {args.envs} "
        f"envs, rollout {ROLLOUT} steps, batch {PPO_SETTINGS['batch_size']}, seed {args.seed}, CPU, torch on 1 thread) |",
        f"| **training wall time** | **{trained.wall_s:.0f} s** |",
        f"| env steps/s while training (PPO's updates included) | {training_rate:.1f} |",
        f"| baseline: random actions, one env on a server (`watch=True`, dynamic) | {server_rate:.1f} env steps/s |",
        f"| random actions, the native vector env PPO trains on | {native_rate:.1f} env steps/s, "
        f"{native_rate / server_rate:.1f}× the baseline |",
        f"| training episodes, of which reached the goal | {trained.episodes}, {trained.successes} |",
        *checks,
        f"| versions | {versions()} |",
    ]


def versions() -> str:
    return ", ".join(f"{name} {metadata.version(name)}" for name in ("stable-baselines3", "torch", "gymnasium"))


def long_run(args: argparse.Namespace) -> list[str]:
    """PPO for `--long-steps` on the warehouse with its people; the curve drawn into docs/learning-curve.svg."""
    native_rate = vector_random_rate(LONG, args.envs, 4 * BASELINE_STEPS)
    trained = train(LONG, args.long_steps, args.envs, LONG_ROLLOUT, args.seed)
    curve = trained.curve
    final = np.mean([rate for _, _, rate in curve[-10:]]) if curve else 0.0
    caption = (
        f"{trained.steps} env steps in {trained.wall_s / 3600:.2f} h on {cpu_model()}, {args.envs} envs; "
        f"success rate of each rollout's training episodes"
    )
    CURVE.write_text(
        line_chart(
            [(steps, rate) for steps, _, rate in curve],
            (0.0, float(max(trained.steps, 1))),
            (0.0, 1.0),
            ("env steps", "success rate"),
            "PPO on simbot/Navigate-v0, warehouse with people, kinematic",
            caption,
        )
    )
    every = max(1, len(curve) // 10)
    rows = [
        f"| {steps} | {wall / 60:.1f} min | {100 * rate:.0f} % |" for steps, wall, rate in curve[every - 1 :: every]
    ]
    return [
        f"PPO (`MultiInputPolicy`, `VecNormalize`, rollout {LONG_ROLLOUT}, seed {args.seed}) on `{ENV_ID}` with "
        f"{', '.join(f'{k}={v!r}' for k, v in LONG.items())}, a native vector env of {args.envs} envs.",
        "",
        "![the success rate of the training episodes as PPO trains](learning-curve.svg)",
        "",
        "| env steps | wall time | success rate of the rollout's episodes |",
        "| --- | --- | --- |",
        *rows,
        "",
        f"Budget {args.long_steps} env steps, trained {trained.steps} in {trained.wall_s / 60:.1f} min "
        f"({trained.steps / trained.wall_s:.1f} env steps/s, PPO's updates included; random actions on the same "
        f"vector env {native_rate:.1f}/s); {trained.episodes} training episodes, {trained.successes} reached the goal; "
        f"the last ten rollouts' mean success rate {100 * final:.0f} %. {versions()}.",
    ]


def vector_random_rate(kwargs: dict[str, Any], envs: int, steps: int) -> float:
    """Env steps per second of random actions on a native vector env of `envs` (start-up not counted)."""
    vector = gymnasium.make_vec(ENV_ID, num_envs=envs, vectorization_mode="vector_entry_point", **kwargs)
    try:
        vector.reset(seed=0)
        started, done = time.perf_counter(), 0
        while done < steps:
            vector.step(vector.action_space.sample())
            done += envs
        return done / (time.perf_counter() - started)
    finally:
        vector.close()


def main(argv: Sequence[str] | None = None) -> int:
    parser = _Parser(prog="bench_learning.py", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--steps",
        type=at_least(1),
        default=DEFAULT_STEPS,
        help=f"training budget in env steps (default: {DEFAULT_STEPS})",
    )
    parser.add_argument("--episodes", type=at_least(1), default=20, help="evaluation episodes per policy (default: 20)")
    parser.add_argument("--seed", type=at_least(0), default=0, help="PPO's and the training env's seed (default: 0)")
    parser.add_argument(
        "--eval-seed", type=at_least(0), default=1000, help="the first evaluation episode's seed (default: 1000)"
    )
    parser.add_argument(
        "--envs", type=at_least(1), default=DEFAULT_ENVS, help=f"envs PPO trains on (default: {DEFAULT_ENVS})"
    )
    parser.add_argument("--long", action="store_true", help="the long run instead (warehouse with people)")
    parser.add_argument(
        "--long-steps",
        type=at_least(LONG_ROLLOUT),
        default=LONG_STEPS,
        help=f"the long run's budget (default: {LONG_STEPS})",
    )
    parser.add_argument("--print-only", action="store_true", help="print the table, leave the docs as they are")
    args = parser.parse_args(argv)
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        print("bench_learning: skipped: stable-baselines3 is not installed (`make bench-learning` installs it)")
        return 0
    table = long_run(args) if args.long else results(args)
    if args.print_only:
        print("\n".join(table))
    elif args.long:
        publish("learning-curve", table, LEARNING_PAGE)
    else:
        publish("learning", table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
