"""Native vector environments: N tugs stepped together, each world in a simulation process's memory.

    envs = gymnasium.make_vec("simbot/Navigate-v0", num_envs=8, vectorization_mode="vector_entry_point",
                              world="warehouse", people=True, physics="kinematic")

returns a `SimbotVectorEnv`: N sub-environments, each the single environment with the same keywords
stepping its own world off the bus (simbot.gym.local), split over `processes` simulation processes
(default: one per core, where there are several envs and cores; else all in this process). No
server process, no Zenoh, no CDR: a step sends each process its envs' actions, and each steps
its worlds together, phase by phase (`simbot.sim.loop.simulation.step_together`: the people of
all its worlds think in one pass, their IMUs sample in one), and sends back their observations as
arrays. docs/learning.md has the measurement behind the default.

Sub-environment i is the single environment: reset with seed s it gives, action for action, the
episode `gymnasium.make(id, **kwargs)` gives after `reset(seed=s)` (tests/test_gym_vector.py).
`reset(seed=S)` seeds sub-env i with S + i (as Gymnasium's own vector envs do); `reset()` first
seeds them with the `seed` option + i. Autoreset follows Gymnasium 1.x's default (`NEXT_STEP`):
the step after an episode ends resets that sub-env (its next seed drawn from its own generator,
as a single env's `reset()` draws it) and returns its first observation with reward 0.
`autoreset_mode="same_step"` resets it in the step that ended it instead, the last observation and
info in `info["final_obs"]` and `info["final_info"]` (what Stable-Baselines3 expects: simbot.gym.sb3).

Cameras render in each sub-env's own render workers, started by its simulation process, and the
frames come back to the world (`cameras_in_process`). Errors: a `num_envs` below 1, or an env that
cannot step off the bus (`watch=True`, `endpoint=`: use `vectorization_mode="async"`; cameras with
`processes=0`), or more envs than memory holds (ENV_BYTES each), is one EnvConfigError naming it
before anything starts. A simulation process that dies raises SimServerError naming the envs it
held and its exit code, and every other process is stopped: nothing is left running.
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import socket
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from multiprocessing.connection import Connection
from typing import Any, cast

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from simbot import memory
from simbot.gym.base import Observation, SimbotEnv
from simbot.gym.errors import EnvConfigError, SimServerError
from simbot.gym.local import LocalSession, step_together
from simbot.gym.options import EnvOptions
from simbot.sim.render.pool import usable_cores

log = logging.getLogger(__name__)

STOP_TIMEOUT_S = 10.0
ENV_BYTES = 48 << 20
"""Memory a sub-env's world takes (measured: 40–46 MB an env, kinematic or dynamic, the empty world
or the warehouse with its people, AMD EPYC, 2026-12-03; 28 MB of it PyBullet's own, at its connect)."""
PROCESS_BYTES = 128 << 20
"""A simulation process's own before its worlds (measured: 122–135 MB with its first env)."""
Step = tuple[Observation, npt.NDArray[np.float64], npt.NDArray[np.bool_], npt.NDArray[np.bool_], list[dict[str, Any]]]


class EnvGroup:
    """Some of a vector env's sub-environments, their worlds stepped together, with autoreset; the
    same code in this process and in a simulation process."""

    def __init__(self, task: str, kwargs: dict[str, Any], count: int, same_step: bool = False) -> None:
        make = _task(task)
        self.same_step = same_step
        """Gymnasium's SAME_STEP autoreset: an ended episode's env is reset in the step that ended it."""
        self.envs: list[SimbotEnv] = []
        try:
            for _ in range(count):
                self.envs.append(make(**kwargs))
        except BaseException:
            self.close()
            raise
        self._ended = [False] * count

    def reset(
        self, seeds: Sequence[int | None], options: dict[str, Any] | None
    ) -> tuple[Observation, list[dict[str, Any]]]:
        results = [env.reset(seed=seed, options=options) for env, seed in zip(self.envs, seeds, strict=True)]
        self._ended = [False] * len(self.envs)
        return _stack([obs for obs, _ in results]), [info for _, info in results]

    def step(self, actions: npt.NDArray[Any]) -> Step:
        """Each env's step, or its reset where its episode ended at the last; the worlds that step
        do so together (`step_together`: every batched system once for all of them)."""
        results: list[tuple[Observation, float, bool, bool, dict[str, Any]]] = []
        stepping = [i for i, ended in enumerate(self._ended) if not ended]
        for i in stepping:
            self.envs[i].step_begin(actions[i])
        sessions = [self.envs[i].session for i in stepping]
        assert all(isinstance(session, LocalSession) for session in sessions)  # a vector env runs off the bus
        reached = iter(step_together(cast(list[LocalSession], sessions), self.envs[0].physics_steps))
        for i, env in enumerate(self.envs):
            if self._ended[i]:
                obs, info = env.reset()
                results.append((obs, 0.0, False, False, info))
                self._ended[i] = False
                continue
            obs, reward, term, trunc, info = env.step_end(next(reached))
            if self.same_step and (term or trunc):
                final_obs, final_info = obs, info
                obs, info = env.reset()
                info = {**info, "final_obs": final_obs, "final_info": final_info}
            self._ended[i] = (term or trunc) and not self.same_step
            results.append((obs, reward, term, trunc, info))
        observations, rewards, terminated, truncated, infos = zip(*results)
        return (
            _stack(observations),
            np.array(rewards, np.float64),
            np.array(terminated, np.bool_),
            np.array(truncated, np.bool_),
            list(infos),
        )

    def close(self) -> None:
        for env in self.envs:
            env.close()


def _task(path: str) -> Callable[..., SimbotEnv]:
    module, name = path.split(":")
    make: Callable[..., SimbotEnv] = getattr(importlib.import_module(module), name)
    return make


def _stack(observations: Sequence[Observation]) -> Observation:
    return {key: np.stack([obs[key] for obs in observations]) for key in observations[0]}


def serve(fd: int) -> None:
    """A simulation process (`python -c`, on the socket `fd`): builds its group from the first
    message, then answers requests until `close`, or until its vector env's process is gone."""
    conn = Connection(fd)
    task, kwargs, count, same_step = conn.recv()
    try:
        group = EnvGroup(task, kwargs, count, same_step)
    except Exception as exc:
        conn.send(("error", exc))
        return
    conn.send(("ok", None))
    try:
        while True:
            try:
                request, args = conn.recv()
            except EOFError:
                return  # the vector env's process ended without closing it
            if request == "close":
                return
            try:
                conn.send(("ok", getattr(group, request)(*args)))
            except Exception as exc:
                conn.send(("error", exc))
    finally:
        group.close()


class _Remote:
    """A simulation process holding some sub-environments, and the socket to it. A process of its own
    (not multiprocessing's), so that no user script is imported again in it."""

    def __init__(self, task: str, kwargs: dict[str, Any], indices: range, same_step: bool) -> None:
        self.indices = indices
        mine, theirs = socket.socketpair()
        code = f"from simbot.gym.vector import serve; serve({theirs.fileno()})"
        self.process = subprocess.Popen(
            [sys.executable, "-c", code], pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL
        )
        theirs.close()
        self.conn = Connection(mine.detach())
        self.ask_raw((task, kwargs, len(indices), same_step))

    def ask(self, request: str, *args: Any) -> None:
        self.ask_raw((request, args))

    def ask_raw(self, message: Any) -> None:
        try:
            self.conn.send(message)
        except OSError:
            raise self._died() from None

    def answer(self) -> Any:
        try:
            status, value = self.conn.recv()
        except (EOFError, OSError):
            raise self._died() from None
        if status == "error":
            raise value
        return value

    def _died(self) -> SimServerError:
        try:
            code = self.process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            code = None
        envs = ", ".join(str(i) for i in self.indices)
        return SimServerError(f"the simulation process of envs {envs} (pid {self.process.pid}) exited with code {code}")

    def close(self) -> None:
        if self.process.poll() is None:
            with contextlib.suppress(OSError):
                self.conn.send(("close", ()))
            try:
                self.process.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                log.warning("simulation process %s did not stop within %g s: killed", self.process.pid, STOP_TIMEOUT_S)
                self.process.kill()
                self.process.wait()
        self.conn.close()


class _Local:
    """Sub-environments in this process (`processes=0`): `_Remote`'s requests as calls."""

    def __init__(self, task: str, kwargs: dict[str, Any], indices: range, same_step: bool) -> None:
        self.indices = indices
        self.group = EnvGroup(task, kwargs, len(indices), same_step)
        self._value: Any = None

    def ask(self, request: str, *args: Any) -> None:
        self._value = getattr(self.group, request)(*args)

    def answer(self) -> Any:
        return self._value

    def close(self) -> None:
        self.group.close()


class SimbotVectorEnv(VectorEnv[Observation, npt.NDArray[np.float32], npt.NDArray[Any]]):
    """N sub-environments of one task; see the module docstring."""

    task = ""
    """The single environment's class, as `module:Class`."""

    def __init__(
        self,
        num_envs: int = 1,
        processes: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise EnvConfigError(f"num_envs {num_envs!r}: must be a whole number ≥ 1")
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        template = _task(self.task)(**kwargs)
        template.close()
        options = template.options
        self.processes = _processes(num_envs, processes, bool(options.observed_cameras))
        if self.processes:  # a simulation process may start render workers: its main module is no user's script
            kwargs = {**kwargs, "cameras_in_process": True}
            options = replace(options, cameras_in_process=True)
        if options.on_bus:
            raise EnvConfigError(f"vectorization_mode='vector_entry_point': {_why_on_bus(options)}")
        if problem := memory.shortfall(
            "num_envs", num_envs, ENV_BYTES, max(self.processes, 1) * PROCESS_BYTES, "an env"
        ):
            raise EnvConfigError(problem)
        self.num_envs = num_envs
        self._first_seed = template.options.seed
        self.single_observation_space = template.observation_space
        self.single_action_space = template.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = {**template.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = None
        self._groups: list[_Remote | _Local] = []
        try:
            self._start(kwargs)
        except BaseException:
            self.close()
            raise

    def _start(self, kwargs: dict[str, Any]) -> None:
        same_step = self.autoreset_mode is AutoresetMode.SAME_STEP
        if self.processes == 0:
            self._groups = [_Local(self.task, kwargs, range(self.num_envs), same_step)]
            return
        bounds = np.linspace(0, self.num_envs, self.processes + 1).round().astype(int)
        self._groups = [
            _Remote(self.task, kwargs, range(a, b), same_step) for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        ]
        self._gather()

    def _all(self, request: str, per_group: Callable[[range], tuple[Any, ...]]) -> list[Any]:
        """Every group asked, then every answer read (`_gather`); a group that cannot be asked (its
        process died) fails the request as one that cannot answer does."""
        asked, failure = [], None
        for group in self._groups:
            try:
                group.ask(request, *per_group(group.indices))
                asked.append(group)
            except Exception as exc:
                failure = failure or exc
        return self._gather(asked, failure)

    def _gather(self, groups: Sequence[_Remote | _Local] | None = None, failure: Exception | None = None) -> list[Any]:
        """The answers of `groups` (every group by default); when one fails, the rest are still read so
        that none is left mid-request, and a dead process closes them all."""
        answers = []
        for group in self._groups if groups is None else groups:
            try:
                answers.append(group.answer())
            except Exception as exc:
                failure = failure or exc
        if failure is not None:
            if isinstance(failure, SimServerError):
                self.close()
            raise failure
        return answers

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        seeds = self._seeds(seed)
        super().reset(seed=seed if isinstance(seed, int) else None)
        answers = self._all("reset", lambda r: ([seeds[i] for i in r], options))
        obs = self._joined([obs for obs, _ in answers])
        return obs, self._vector_info([info for _, infos in answers for info in infos])

    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs if self._started else [self._first_seed + i for i in range(self.num_envs)]
        if isinstance(seed, int):
            return [seed + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise EnvConfigError(f"reset seed: {len(seeds)} seeds for {self.num_envs} envs")
        return seeds

    def step(
        self, actions: npt.NDArray[np.float32]
    ) -> tuple[Observation, npt.NDArray[Any], npt.NDArray[Any], npt.NDArray[Any], dict[str, Any]]:
        obs, rewards, terminated, truncated, infos = self.step_each(actions)
        return obs, rewards, terminated, truncated, self._vector_info(infos)

    def step_each(self, actions: npt.NDArray[np.float32]) -> Step:
        """`step`, with each sub-env's info dict as it gave it (what a per-env API, Stable-Baselines3's, wants)."""
        values = np.asarray(actions)
        if values.shape[:1] != (self.num_envs,):
            raise ValueError(f"actions of shape {values.shape}, expected ({self.num_envs}, ...)")
        answers = self._all("step", lambda r: (values[r.start : r.stop],))
        join = np.concatenate
        obs = self._joined([a[0] for a in answers])
        infos = [info for a in answers for info in a[4]]
        return obs, join([a[1] for a in answers]), join([a[2] for a in answers]), join([a[3] for a in answers]), infos

    def _joined(self, parts: list[Observation]) -> Observation:
        self._started = True
        return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}

    def _vector_info(self, infos: list[dict[str, Any]]) -> dict[str, Any]:
        merged: dict[str, Any] = {}
        for i, info in enumerate(infos):
            merged = self._add_info(merged, info, i)
        return merged

    _started = False

    def close_extras(self, **kwargs: Any) -> None:
        groups, self._groups = self._groups, []
        for group in groups:
            group.close()


def _processes(num_envs: int, asked: int | None, cameras: bool) -> int:
    """Simulation processes: as asked (0: this process), else one per core for several envs (at
    least one for an env with cameras, whose render workers this process is not to start)."""
    if asked is None:
        several = min(num_envs, usable_cores())
        return several if several > 1 or cameras else 0
    if isinstance(asked, bool) or not isinstance(asked, int) or not 0 <= asked <= num_envs:
        raise EnvConfigError(
            f"processes {asked!r}: must be a whole number from 0 (this process) to num_envs ({num_envs})"
        )
    return asked


def _autoreset_mode(asked: AutoresetMode | str) -> AutoresetMode:
    """NEXT_STEP (Gymnasium's default) or SAME_STEP; EnvConfigError naming any other."""
    modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
    for mode in modes:
        if asked in (mode, mode.value):
            return mode
    raise EnvConfigError(f"autoreset_mode {asked!r}: one of {', '.join(m.value for m in modes)}")


def _why_on_bus(options: EnvOptions) -> str:
    """Why an env cannot batch, and what to do instead."""
    if options.endpoint is not None or options.watch:
        given = "endpoint=" if options.endpoint is not None else "watch=True"
        return f"{given} needs a server on the bus per env; use vectorization_mode='async'"
    return (
        f"cameras {', '.join(options.observed_cameras)} with processes=0 would start their render workers from this "
        "process; use processes ≥ 1, or cameras_in_process=True in a script guarded by if __name__ == '__main__'"
    )


class NavigateVectorEnv(SimbotVectorEnv):
    """simbot/Navigate-v0, N at a time."""

    task = "simbot.gym.navigate:NavigateEnv"


class DockVectorEnv(SimbotVectorEnv):
    """simbot/Dock-v0, N at a time."""

    task = "simbot.gym.dock:DockEnv"
