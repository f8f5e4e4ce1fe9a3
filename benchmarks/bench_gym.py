"""Benchmark of simbot's Gymnasium environments: env steps per second of `simbot/Navigate-v0` in
Gymnasium's async vector env with 1, 2 and 4 envs, dynamic and kinematic, against a bare PyBullet
loop in the same run.

One run, one machine, so the ratio holds where the machine is shared:

1. bare loop: bench_server's, the warehouse and the robot in PyBullet alone, the robot's wheels
   turning as (0.3 m/s, 0.1 rad/s) turns them, `stepSimulation` at 1 kHz and nothing else; one
   control period of it (100 steps) counts as an env step: what a step would cost if it were
   physics only. Measured before each vector env, each row against its own;
2. `gymnasium.make_vec("simbot/Navigate-v0", num_envs=N, vectorization_mode="async")` in the
   warehouse, its workers spawned (docs/learning.md says why): each env in a process of its own
   with its own lockstep server (physics, lidars, contacts, odometry, and the bus between them),
   every env given (0.3, 0.1) each step; figures are env steps per wall second of all envs
   together, counted after a few warm-up steps (an episode that ends resets itself, as in
   training, and its reset counts);
3. the same with one 160×120 camera (`camera_front`) in the observation;
4. both again with `physics="kinematic"` (the server's kinematic stepper at 200 Hz: 20 physics
   steps an env step instead of 100), against the same bare loop of the dynamic physics.

The start-up column is the wall time from `make_vec` to the end of the first `reset`: the servers
start in parallel, one per env.

    python benchmarks/bench_gym.py [--envs 1,2,4] [--seconds S] [--control-period S]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from typing import Any, NoReturn

import gymnasium
import numpy as np
from bench_server import STEP_S, bare_loop
from tables import publish

import simbot.gym  # noqa: F401  registers simbot/Navigate-v0
from simbot.gym.options import PHYSICS

ENV_ID = "simbot/Navigate-v0"
WORLD = "warehouse"
"""The environments' default world, and bench_server's bare loop's."""
CAMERA = "camera_front"
CAMERA_SIZE = (160, 120)
ACTION = (0.3, 0.1)
"""(v, ω) every env gets each step: what the bare loop's wheel speeds drive (bench_server's LEFT, RIGHT)."""
WARM_UP_STEPS = 5


class _Parser(argparse.ArgumentParser):
    """A bad argument is one line and exit 2, no usage block."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def env_counts(text: str) -> list[int]:
    """`1,2,4` → [1, 2, 4]; each at least 1."""
    try:
        counts = [int(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, got {text!r}") from None
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(f"expected env counts of at least 1, got {text!r}")
    return counts


def positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def bare_env_steps(seconds: float, control_period: float) -> float:
    """Env steps per wall second of PyBullet alone: bench_server's bare loop (the warehouse, the
    robot at the server's spawn, its wheels driven at ACTION's speeds, 1 kHz), one control period
    of sim time per env step."""
    return bare_loop(seconds, driving=True) / control_period


def vector_env_steps(envs: int, seconds: float, kwargs: dict[str, Any]) -> tuple[float, float]:
    """(env steps per wall second, all envs together; seconds from make_vec to the first reset's end)."""
    started = time.perf_counter()
    vector = gymnasium.make_vec(
        ENV_ID, num_envs=envs, vectorization_mode="async", vector_kwargs={"context": "spawn"}, **kwargs
    )
    try:
        vector.reset(seed=0)
        startup = time.perf_counter() - started
        action = np.tile(np.asarray(ACTION, dtype=np.float32), (envs, 1))
        for _ in range(WARM_UP_STEPS):
            vector.step(action)
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            vector.step(action)
            steps += 1
        return steps * envs / (time.perf_counter() - start), startup
    finally:
        vector.close()


def row(physics: str, envs: int, camera: bool, rate: float, startup: float, bare: float) -> str:
    looks = f"{CAMERA} {CAMERA_SIZE[0]}×{CAMERA_SIZE[1]}" if camera else "none"
    return f"| {physics} | {envs} | {looks} | {rate:.1f} | {rate / envs:.1f} | {rate / bare:.2f} | {startup:.1f} s |"


def measure(args: argparse.Namespace) -> list[str]:
    """The table: the bare loop measured before each vector env, each row against its own."""
    table = [
        "| physics | envs (async) | camera in the observation | env steps/s, all envs | per env | ÷ bare loop | start-up |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    bares = []
    for physics in PHYSICS:
        base = {"world": WORLD, "control_period": args.control_period, "physics": physics}
        for camera in (False, True):
            kwargs = {**base, "cameras": (CAMERA,), "camera_size": CAMERA_SIZE} if camera else dict(base)
            for envs in args.envs:
                bare = bare_env_steps(min(args.seconds, 3.0), args.control_period)
                rate, startup = vector_env_steps(envs, args.seconds, kwargs)
                bares.append(bare)
                table.append(row(physics, envs, camera, rate, startup, bare))
                print(table[-1], file=sys.stderr, flush=True)
    steps = round(args.control_period / STEP_S)
    table.append(
        f"| bare PyBullet loop, {WORLD} + robot, wheels driven, {steps} physics steps an env step | — | — | "
        f"{np.median(bares):.1f} (median of {len(bares)}; {min(bares):.1f}–{max(bares):.1f}) | — | 1 | — |"
    )
    return table


def main(argv: Sequence[str] | None = None) -> int:
    parser = _Parser(prog="bench_gym.py", description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=env_counts, default=[1, 2, 4], help="env counts (default: 1,2,4)")
    parser.add_argument("--seconds", type=positive, default=8.0, help="wall seconds per measurement")
    parser.add_argument("--control-period", type=positive, default=0.1, help="sim seconds per env step")
    args = parser.parse_args(argv)
    publish("gym", measure(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
