"""Benchmark of learning on simbot's environments: PPO on Navigate-v0's easy variant against the random policy.

One run, one machine, so the comparison holds where the machine is shared:

1. Stable-Baselines3's own env checker (`stable_baselines3.common.env_checker.check_env`) on
   `simbot/Navigate-v0` and `simbot/Dock-v0` (empty world): pass or fail, and its warnings;
2. PPO (`MultiInputPolicy` on the Dict observation, on the CPU, torch on one thread, observations
   and rewards normalised by `VecNormalize`, seeded) trained on the easy variant for a fixed
   budget of env steps (`--steps`), one env, so one server;
3. the trained policy (deterministic: the Gaussian's mean) and `simbot.gym.policies.RandomPolicy`
   over the same `--episodes` seeded episodes of the same variant: success rates, mean returns
   (the environment's reward, not normalised), their ratio, mean episode lengths.

The easy variant is `simbot/Navigate-v0` in the empty world with (v, ω) bounded to 1 m/s and
1 rad/s, 60 steps of 0.1 s an episode, and the goal 2 m straight ahead of the start with the start's
heading; the start is drawn anywhere in ±6 m with any heading from the episode's seed. The
environment takes a start and a goal as `reset` options; `TwoMetresAhead`, a wrapper of this file,
gives them on every reset (Stable-Baselines3's own resets give none).

The budget: an env step is a control period (0.1 s) of the server's physics, some 40 ms of CPU on
the 2-core machine this was written on, where the variant ran at about 25 env steps/s with random
actions and PPO trained at about 20 (its updates included): 10 240 steps is some 9 minutes of
training, 11 with the checks and the evaluation. Needs the `learning` extra (`make bench-learning`
installs it).

    python benchmarks/bench_learning.py [--steps N] [--episodes N] [--seed S] [--eval-seed S]
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import metadata
from typing import Any, NoReturn

import gymnasium
import numpy as np
from tables import publish

import simbot.gym  # noqa: F401  registers simbot/Navigate-v0 and simbot/Dock-v0
from simbot.gym.policies import RandomPolicy

ENVIRONMENTS = ("simbot/Navigate-v0", "simbot/Dock-v0")
ENV_ID = "simbot/Navigate-v0"
EASY: dict[str, Any] = {
    "world": "empty",
    "control_period": 0.1,
    "max_linear": 1.0,
    "max_angular": 1.0,
    "max_episode_steps": 60,
}
"""Navigate-v0's keywords for the easy variant (the goal comes from `TwoMetresAhead`)."""
GOAL_AHEAD_M = 2.0
START_HALF_SIDE_M = 6.0
"""Starts are drawn in [−6, 6]² m: with the goal 2 m on, inside the empty world's 20 × 20 m area."""
PPO_SETTINGS: dict[str, Any] = {"n_steps": 256, "batch_size": 64, "n_epochs": 10, "learning_rate": 3e-4, "gamma": 0.99}
"""Short rollouts, so that the small budget makes many updates (40 at the default budget)."""
DEFAULT_STEPS = 10_240
PROGRESS_EVERY = 1024


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


class TwoMetresAhead(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Navigate-v0 with the goal `GOAL_AHEAD_M` straight ahead of the start, at the start's heading.

    Each reset draws the start from the episode's seed (the one given, else one drawn from the
    generator the last seeded reset made) and hands the start and goal to the environment's
    `reset(options=...)`, with the same seed, so `info["seed"]` replays the episode."""

    def __init__(self, env: gymnasium.Env[Any, Any]) -> None:
        super().__init__(env)
        self._seeds = np.random.default_rng(0)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        if seed is not None:
            self._seeds = np.random.default_rng(seed)
            episode = seed
        else:
            episode = int(self._seeds.integers(2**31 - 1))
        draw = np.random.default_rng(episode)
        x, y = (float(v) for v in draw.uniform(-START_HALF_SIDE_M, START_HALF_SIDE_M, 2))
        yaw = float(draw.uniform(-math.pi, math.pi))
        goal = (x + GOAL_AHEAD_M * math.cos(yaw), y + GOAL_AHEAD_M * math.sin(yaw), yaw)
        return self.env.reset(seed=episode, options={"start": (x, y, yaw), "goal": goal, **(options or {})})


def make_easy() -> gymnasium.Env[Any, Any]:
    return TwoMetresAhead(gymnasium.make(ENV_ID, **EASY))


def check_envs() -> list[str]:
    """Rows: Stable-Baselines3's check_env on each environment, pass or fail, with its warnings."""
    from stable_baselines3.common.env_checker import check_env

    rows = []
    for env_id in ENVIRONMENTS:
        env = gymnasium.make(env_id, **EASY)
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


def train(steps: int, seed: int) -> Training:
    """PPO on the easy variant for `steps` env steps, seeded, on the CPU."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # the server has the other core: a second thread would only queue for it

    class Progress(BaseCallback):
        """Counts the training episodes and their successes; a line on stderr every PROGRESS_EVERY steps."""

        def __init__(self) -> None:
            super().__init__()
            self.episodes = self.successes = 0
            self.started = time.perf_counter()

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    self.episodes += 1
                    self.successes += bool(info.get("success"))
            if self.num_timesteps % PROGRESS_EVERY == 0:
                elapsed = time.perf_counter() - self.started
                print(
                    f"  {self.num_timesteps} steps, {elapsed:.0f} s, {self.num_timesteps / elapsed:.1f} steps/s, "
                    f"{self.episodes} episodes, {self.successes} reached the goal",
                    file=sys.stderr,
                    flush=True,
                )
            return True

    vector = VecNormalize(make_vec_env(make_easy, n_envs=1, seed=seed), norm_obs=True, norm_reward=True)
    try:
        model = PPO("MultiInputPolicy", vector, seed=seed, device="cpu", verbose=0, **PPO_SETTINGS)
        progress = Progress()
        started = time.perf_counter()
        model.learn(total_timesteps=steps, callback=progress)
        wall = time.perf_counter() - started
        vector.training = False
        return Training(model, vector, wall, int(model.num_timesteps), progress.episodes, progress.successes)
    finally:
        vector.close()


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
    print(f"training PPO for {args.steps} env steps ...", file=sys.stderr, flush=True)
    trained = train(args.steps, args.seed)
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
    versions = ", ".join(f"{name} {metadata.version(name)}" for name in ("stable-baselines3", "torch", "gymnasium"))
    variant = (
        f"`{ENV_ID}`, empty world, goal {GOAL_AHEAD_M:g} m straight ahead at the start's heading, start anywhere in "
        f"±{START_HALF_SIDE_M:g} m, (v, ω) within 1 m/s and 1 rad/s, {EASY['max_episode_steps']} steps of 0.1 s"
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
        f"| budget | {args.steps} env steps (PPO `MultiInputPolicy`, `VecNormalize`, 1 env, seed {args.seed}, "
        f"n_steps {PPO_SETTINGS['n_steps']}, batch {PPO_SETTINGS['batch_size']}, CPU, torch on 1 thread) |",
        f"| training wall time | {trained.wall_s:.0f} s |",
        f"| env steps/s while training (PPO's updates included) | {trained.steps / trained.wall_s:.1f} |",
        f"| env steps/s of the random policy's episodes | {sum(chance.lengths) / chance.wall_s:.1f} |",
        f"| training episodes, of which reached the goal | {trained.episodes}, {trained.successes} |",
        *checks,
        f"| versions | {versions} |",
    ]


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
    parser.add_argument("--print-only", action="store_true", help="print the table, leave docs/speed.md as it is")
    args = parser.parse_args(argv)
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        print("bench_learning: skipped: stable-baselines3 is not installed (`make bench-learning` installs it)")
        return 0
    table = results(args)
    if args.print_only:
        print("\n".join(table))
    else:
        publish("learning", table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
