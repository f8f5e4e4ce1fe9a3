"""Episodes across Ray actors: one environment, and so one simbot world, per actor.

An experiment (K episodes of one policy in one environment) is embarrassingly parallel: each
episode needs only its seed. `run_episodes` starts A actors (Ray's processes, anywhere in the Ray
cluster), each of which makes one environment (its world in the actor's process, off the bus,
or, when watched, its own lockstep server subprocess on that actor's machine) and runs the
episodes it is handed, seed by seed, until none are left. The
results come back sorted by episode, one `EpisodeResult` each.

Why it repeats: episode i always gets seed `seed + i` whichever actor runs it, the environment's
reset with a seed fixes its world, and a policy with per-episode state (`RandomPolicy`) is
reset with the same seed; so the same arguments give the same results on one machine or fifty
(across CPU models, to the last bits of a float: docs/reproducibility.md).

Ray is an optional dependency (`pip install 'simbot[gym,ray]'`): this module imports it at its top,
and nothing else in simbot.gym imports this module, so `import simbot.gym` never needs Ray.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium
import ray
from ray.util import ActorPool

from simbot.gym.policies import Policy, Resettable, check_policy, make_policy

logger = logging.getLogger(__name__)

COLUMNS = ("episode", "seed", "success", "steps", "return", "collisions", "clipped_actions")
"""The results table's columns, in order (`EpisodeResult.row`)."""


class ExperimentError(ValueError):
    """A user's mistake, in one line: an unknown environment or a bad count (found before any actor
    starts), or an option the environment refuses (found by the actors making it)."""


@dataclass(frozen=True)
class EpisodeResult:
    """What one episode came to: its index and seed, whether the environment said it succeeded
    (`info["success"]` at its end), its length in steps, the summed reward, and the environment's
    counts of collisions and of actions it had to clip to the action space."""

    episode: int
    seed: int
    success: bool
    steps: int
    episode_return: float
    collisions: int
    clipped_actions: int

    def row(self) -> dict[str, Any]:
        """The result under `COLUMNS`' names (`return` for `episode_return`), for a CSV row."""
        fields = asdict(self)
        fields["return"] = fields.pop("episode_return")
        return {name: fields[name] for name in COLUMNS}


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """Episode i's seed: `seed + i`, distinct, and the same whichever actor runs it."""
    return [seed + i for i in range(episodes)]


def run_episode(env: Any, policy: Policy, episode: int, seed: int, max_steps: int | None = None) -> EpisodeResult:
    """One episode of `policy` in `env` from `reset(seed=seed)` until it terminates or is truncated
    (or after `max_steps`, for an environment without a time limit of its own)."""
    obs, info = env.reset(seed=seed)
    if isinstance(policy, Resettable):
        policy.reset(seed)
    total, steps, done = 0.0, 0, False
    while not done and (max_steps is None or steps < max_steps):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += float(reward)
        steps += 1
        done = bool(terminated or truncated)
    return EpisodeResult(
        episode=episode,
        seed=seed,
        success=bool(info.get("success", False)),
        steps=steps,
        episode_return=total,
        collisions=int(info.get("collisions", 0)),
        clipped_actions=int(info.get("clipped_actions", 0)),
    )


def check_env(env_id: str) -> None:
    """ExperimentError with one line when `env_id` is not a registered environment (simbot's are
    registered by importing simbot.gym, as importing this module does); checked here, before an
    actor fails on it."""
    if env_id not in gymnasium.registry:
        known = sorted(name for name in gymnasium.registry if name.startswith("simbot/"))
        raise ExperimentError(f"unknown environment {env_id!r}: simbot's are {', '.join(known) or 'none'}")


class EpisodeActor:
    """One environment and one policy, living in one Ray actor for the whole experiment: the
    server starts once per actor, not once per episode (seconds each). Ray imports this module in
    the actor's process, and with it simbot.gym, which registers the environments there.

    A failure to make the environment is kept for `ready()` rather than raised: Ray would wrap it
    in an actor-death error several layers deep, and a bad option must reach the user as its line."""

    def __init__(
        self, env_id: str, env_kwargs: Mapping[str, Any], policy: str | Policy, max_steps: int | None = None
    ) -> None:
        self.env: Any = None
        self.failure: tuple[bool, str] | None = None
        try:
            self.env = gymnasium.make(env_id, **env_kwargs)
            self.policy = make_policy(policy, self.env.action_space)
        except (ValueError, TypeError) as exc:  # EnvConfigError, PolicyError, a keyword the env does not take
            self.failure = (True, str(exc))
        except Exception as exc:  # the server did not start: the user's run fails, not their input
            self.failure = (False, f"{type(exc).__name__}: {exc}")
        self.max_steps = max_steps
        logger.info("actor %d: %s %s", os.getpid(), env_id, "ready" if self.failure is None else self.failure[1])

    def ready(self) -> tuple[bool, str] | None:
        """None when the environment is up; else (whether it is the user's mistake, the one line)."""
        return self.failure

    def run(self, episode: int, seed: int) -> EpisodeResult:
        return run_episode(self.env, self.policy, episode, seed, self.max_steps)

    def close(self) -> None:
        """Ends the environment's server; called before the actor goes, so no server outlives it."""
        if self.env is not None:
            self.env.close()


def run_episodes(
    env_id: str,
    policy: str | Policy,
    episodes: int,
    num_actors: int = 1,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    cpus_per_actor: float = 1.0,
    max_steps: int | None = None,
) -> list[EpisodeResult]:
    """`episodes` episodes of `policy` (`random`, `scripted`, `module:function`, or a callable Ray can
    pickle) in `env_id`, across `num_actors` Ray actors, each owning one environment made with
    `env_kwargs`; episode i has seed `seed + i`. Results sorted by episode.

    Uses the Ray session already started (`ray.init`, `start_ray`), or starts a local one as Ray
    does by default. `cpus_per_actor`: what Ray reserves for each actor; the actor's server runs
    beside it, so 1 per actor keeps a machine from taking more environments than it has cores.
    ExperimentError for a bad count, environment, option or policy (an option only once the
    actors have tried it); RuntimeError when an environment's server does not start."""
    if episodes < 1:
        raise ExperimentError(f"episodes must be ≥ 1, not {episodes}")
    if num_actors < 1:
        raise ExperimentError(f"actors must be ≥ 1, not {num_actors}")
    check_env(env_id)
    check_policy(policy)
    remote = ray.remote(EpisodeActor).options(num_cpus=cpus_per_actor)
    kwargs = dict(env_kwargs or {})
    actors = [remote.remote(env_id, kwargs, policy, max_steps) for _ in range(min(num_actors, episodes))]
    try:
        _check_ready(actors)
        jobs = list(enumerate(episode_seeds(seed, episodes)))
        results: list[EpisodeResult] = list(
            ActorPool(actors).map_unordered(lambda actor, job: actor.run.remote(*job), jobs)
        )
    finally:
        _close(actors)
    return sorted(results, key=lambda result: result.episode)


def _check_ready(actors: Sequence[Any]) -> None:
    """Waits until every actor has made its environment; the first failure as ExperimentError (the
    user's option) or RuntimeError (a server that did not start)."""
    for failure in ray.get([actor.ready.remote() for actor in actors]):
        if failure is not None:
            users, line = failure
            raise (ExperimentError if users else RuntimeError)(line)


def _close(actors: Sequence[Any]) -> None:
    """Closes each actor's environment (its server), then ends the actors; an actor already dead
    (its server gone wrong) is only logged, so the others still close."""
    for actor, closed in zip(actors, [actor.close.remote() for actor in actors]):
        try:
            ray.get(closed, timeout=60)
        except Exception as exc:  # a dead actor must not keep the others' servers running
            logger.warning("an actor did not close its environment: %s", exc)
        ray.kill(actor)


def start_ray(address: str | None = None, num_cpus: int | None = None, verbose: bool = False) -> bool:
    """Joins the Ray cluster at `address` (`auto`: the one `ray start` made on this machine), or
    starts a local Ray with `num_cpus` CPUs; does nothing if this process already has a session.
    True when it started one (the caller shuts it down). Quiet unless `verbose`: the actors' logs,
    the servers' included, stay in Ray's log files instead of the terminal."""
    if ray.is_initialized():
        return False
    quiet: dict[str, Any] = {"log_to_driver": verbose, "logging_level": logging.INFO if verbose else logging.WARNING}
    if address:
        ray.init(address=address, **quiet)
    else:
        ray.init(num_cpus=num_cpus, include_dashboard=False, **quiet)
    return True
