"""Benchmark of simbot's Gymnasium environments: env steps per second of `simbot/Navigate-v0` against
two baselines measured in the same run.

One run, one machine, so the ratios hold where the machine is shared. The baselines:

1. bare loader loop: bench_server's, the warehouse and the robot in PyBullet alone, the robot's
   wheels turning as (0.3 m/s, 0.1 rad/s) turns them, `stepSimulation` at 1 kHz and nothing
   else; one control period of it (100 steps) counts as an env step: what a step would cost if it
   were the dynamic physics only;
2. ray ceiling: the two lidars' 1440 rays of one env step, cast in one `rayTestBatch` call, the
   robot where seed 0's episode starts in the warehouse with its people: what a step would cost if
   it were its rays only (no env step can be cheaper: every step casts them).

The measurements, every env given (0.3, 0.1) each step, counted after a few warm-up steps (an
episode that ends resets itself, as in training, and its reset counts):

- kinematic physics in the warehouse with its people, lidar only (the learning set-up of issue
  47): the single env off the bus, and the native vector env
  (`vectorization_mode="vector_entry_point"`) with its sub-envs in this process or in one
  simulation process per core: the measurement behind its default;
- the same with one 160×120 camera (`camera_front`) per env: in the native vector env (each
  sub-env's render worker hands its frames back), and in Gymnasium's async vector env with a
  server each (workers spawned), for comparison;
- dynamic physics in the warehouse, one env: off the bus, and on a server (`watch=True`), each
  against the bare loader loop.

The start-up column is the wall time from `make`/`make_vec` to the end of the first `reset`.

    python benchmarks/bench_gym.py [--seconds S]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

import gymnasium
import numpy as np
from bench_server import STEP_S, bare_loop
from tables import publish

import simbot.gym  # noqa: F401  registers simbot/Navigate-v0
from simbot.gym.base import SimbotEnv
from simbot.gym.local import LocalSession
from simbot.sim.bullet import pb
from simbot.sim.physics.rays import Batch

ENV_ID = "simbot/Navigate-v0"
WORLD = "warehouse"
"""The environments' default world, and bench_server's bare loop's."""
LEARNING: dict[str, Any] = {"world": WORLD, "people": True, "physics": "kinematic"}
CAMERA = "camera_front"
CAMERA_SIZE = (160, 120)
ACTION = (0.3, 0.1)
"""(v, ω) every env gets each step: what the bare loop's wheel speeds drive (bench_server's LEFT, RIGHT)."""
WARM_UP_STEPS = 5
CONTROL_PERIOD_S = 0.1


class _Parser(argparse.ArgumentParser):
    """A bad argument is one line and exit 2, no usage block."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def bare_env_steps(seconds: float) -> float:
    """Env steps per wall second of bench_server's bare loop, one control period of sim time an env step."""
    return bare_loop(seconds, driving=True) / CONTROL_PERIOD_S


def ray_ceiling(seconds: float) -> float:
    """Env steps per wall second if a step were its two lidars' rays alone, cast in one call."""
    env = gymnasium.make(ENV_ID, **LEARNING)
    try:
        env.reset(seed=0)
        unwrapped = env.unwrapped
        assert isinstance(unwrapped, SimbotEnv) and isinstance(unwrapped.session, LocalSession)
        physics = unwrapped.session.sim_world.physics
        cast: list[tuple[np.ndarray, np.ndarray, int]] = []
        original = physics._rays.cast

        def recording(batches: Sequence[Batch]) -> list[np.ndarray]:
            for starts, ends, body in batches:
                cast.append((starts, ends, ~physics._rays.bullet.blind_to(body) if body else -1))
            return original(batches)

        physics._rays.cast = recording  # type: ignore[method-assign]
        env.step(np.asarray(ACTION, np.float32))
        physics._rays.cast = original  # type: ignore[method-assign]
        starts = np.concatenate([c[0] for c in cast])
        ends = np.concatenate([c[1] for c in cast])
        mask, client = cast[0][2], physics.client
        calls, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            pb.rayTestBatch(starts, ends, collisionFilterMask=mask, physicsClientId=client)
            calls += 1
        print(f"ray ceiling: {len(starts)} rays a step", file=sys.stderr)
        return calls / (time.perf_counter() - start)
    finally:
        env.close()


def stepped(make: Callable[[], Any], envs: int, seconds: float) -> tuple[float, float]:
    """(env steps per wall second of all envs, seconds from `make()` to the first reset's end)."""
    started = time.perf_counter()
    env = make()
    try:
        env.reset(seed=0)
        startup = time.perf_counter() - started
        action = np.asarray(ACTION, dtype=np.float32)
        action = np.tile(action, (envs, 1)) if envs > 1 or hasattr(env, "num_envs") else action
        for _ in range(WARM_UP_STEPS):
            _step(env, action)
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            _step(env, action)
            steps += 1
        return steps * envs / (time.perf_counter() - start), startup
    finally:
        env.close()


def _step(env: Any, action: np.ndarray) -> None:
    _, _, terminated, truncated, _ = env.step(action)
    if not hasattr(env, "num_envs") and (terminated or truncated):
        env.reset()


def native(envs: int, processes: int, camera: bool = False) -> Callable[[], Any]:
    kwargs = {**LEARNING, "cameras": (CAMERA,), "camera_size": CAMERA_SIZE} if camera else LEARNING
    return lambda: gymnasium.make_vec(
        ENV_ID, num_envs=envs, vectorization_mode="vector_entry_point", processes=processes, **kwargs
    )


def cameras_async(envs: int) -> Callable[[], Any]:
    kwargs = {**LEARNING, "cameras": (CAMERA,), "camera_size": CAMERA_SIZE}
    return lambda: gymnasium.make_vec(
        ENV_ID, num_envs=envs, vectorization_mode="async", vector_kwargs={"context": "spawn"}, **kwargs
    )


def single(**kwargs: Any) -> Callable[[], Any]:
    return lambda: gymnasium.make(ENV_ID, **kwargs)


CASES: list[tuple[str, int, str, Callable[[], Any]]] = [
    ("kinematic, people, lidar only: one env, off the bus", 1, "this one", single(**LEARNING)),
    ("the same, native vector env", 2, "2 simulation", native(2, 2)),
    ("the same, native vector env", 4, "this one", native(4, 0)),
    ("the same, native vector env", 4, "2 simulation", native(4, 2)),
    ("the same, native vector env", 8, "2 simulation", native(8, 2)),
    ("the same, native vector env", 16, "2 simulation", native(16, 2)),
    (
        f"the same with {CAMERA} {CAMERA_SIZE[0]}×{CAMERA_SIZE[1]}: native vector env",
        2,
        "2 simulation",
        native(2, 2, True),
    ),
    (
        f"the same with {CAMERA} {CAMERA_SIZE[0]}×{CAMERA_SIZE[1]}: native vector env",
        4,
        "2 simulation",
        native(4, 2, True),
    ),
    (f"the same with {CAMERA}: async vector env, a server each", 2, "2 workers + 2 servers", cameras_async(2)),
    ("dynamic, warehouse: one env, off the bus", 1, "this one", single(world=WORLD)),
    (
        "dynamic, warehouse: one env on a server (`watch=True`)",
        1,
        "this one + a server",
        single(world=WORLD, watch=True),
    ),
]


def measure(seconds: float) -> list[str]:
    """The table: the baselines measured around the rows, each row against their medians."""
    bares, ceilings, rows = [], [], []
    for name, envs, processes, make in CASES:
        bares.append(bare_env_steps(min(seconds, 3.0)))
        ceilings.append(ray_ceiling(min(seconds, 3.0)))
        rate, startup = stepped(make, envs, seconds)
        rows.append((name, envs, processes, rate, startup))
        print(f"{name} ({envs}, {processes}): {rate:.1f} env steps/s", file=sys.stderr, flush=True)
    bare, ceiling = float(np.median(bares)), float(np.median(ceilings))
    table = [
        "| measurement | envs | processes stepping worlds | env steps/s, all envs | ÷ bare loader loop | ÷ ray ceiling | start-up |",
        "| --- | --- | --- | --- | --- | --- | --- |",
        *(
            f"| {name} | {envs} | {processes} | {rate:.1f} | {rate / bare:.2f} | {rate / ceiling:.2f} | {startup:.1f} s |"
            for name, envs, processes, rate, startup in rows
        ),
        f"| baseline: bare loader loop, {WORLD} + robot, wheels driven, {round(CONTROL_PERIOD_S / STEP_S)} physics "
        f"steps an env step | — | one | {bare:.1f} (median of {len(bares)}; {min(bares):.1f}–{max(bares):.1f}) | 1 | "
        f"{bare / ceiling:.2f} | — |",
        f"| baseline: ray ceiling, one env step's 1440 lidar rays in one `rayTestBatch`, {WORLD} with people | — | one | "
        f"{ceiling:.1f} (median of {len(ceilings)}; {min(ceilings):.1f}–{max(ceilings):.1f}) | {ceiling / bare:.2f} | 1 | — |",
    ]
    return table


def main(argv: Sequence[str] | None = None) -> int:
    parser = _Parser(prog="bench_gym.py", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=positive, default=8.0, help="wall seconds per measurement")
    args = parser.parse_args(argv)
    publish("gym", measure(args.seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
