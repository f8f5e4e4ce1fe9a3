"""Policies for simbot's environments: a baseline to compare a learnt policy against, and the way a
user's own policy is named on the command line.

A policy is any callable `policy(obs) -> action` (`Policy`); `simbot experiment --policy` names one
as `random`, `scripted` or `module:function`. Two are built in:

- `RandomPolicy`: uniform over any Box action space, drawn from its own generator, seeded per
  episode (`reset(seed)`), so that an experiment with the same seeds repeats exactly;
- `ScriptedPolicy`, for Navigate-v0's (v, ω): turns to `obs["goal"]`, drives to it and turns to its
  heading, turning away while the merged scan shows an obstacle ahead nearer than a threshold. It
  is the floor a learnt policy must beat, and a check that a task can be solved at all. An action
  space with more components (Dock-v0's attach) gets their upper bounds: attach asked every step.

A policy with state per episode (the random one's generator, the scripted one's detour) has a
`reset(seed)` method (`Resettable`); the runner calls it before each episode with its seed. The
built-in ones are plain classes of this module, so Ray ships them to its actors by reference.
"""

from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

logger = logging.getLogger(__name__)

Observation = Mapping[str, Any]
Action = np.ndarray
Policy = Callable[[Observation], Any]
"""`policy(obs) -> action`: an observation of the environment in, an action of its space out."""

BUILT_IN = ("random", "scripted")


class PolicyError(ValueError):
    """A policy name that names nothing: not built in, or a `module:function` that does not import."""


@runtime_checkable
class Resettable(Protocol):
    """A policy with state per episode: the runner calls `reset(seed)` before each episode."""

    def reset(self, seed: int) -> None: ...


class RandomPolicy:
    """Uniform actions over a Box, from a generator of its own: the floor any policy must beat.

    Its own generator rather than the space's `sample()`: the space's generator is shared with
    whatever else samples it, and `reset(seed)` must make an episode's actions depend on its seed
    alone."""

    def __init__(self, low: Any, high: Any, seed: int | None = None) -> None:
        self.low = np.asarray(low, dtype=np.float32)
        self.high = np.asarray(high, dtype=np.float32)
        self.rng = np.random.default_rng(seed)

    @classmethod
    def for_space(cls, space: Any, seed: int | None = None) -> RandomPolicy:
        """For a gymnasium Box action space (its `low` and `high`)."""
        return cls(space.low, space.high, seed)

    def reset(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: Observation) -> Action:
        return self.rng.uniform(self.low, self.high).astype(np.float32)


@dataclass
class ScriptedPolicy:
    """Turn to the goal, drive to it, turn to its heading; turn away from what the scan shows ahead.

    `obs["goal"]` is the goal in the robot's frame (x forward, y left, yaw); `obs["scan"]` the merged
    360° ranges in base_link, bin i centred on −π + i·2π/N (the merger's bins). One motion at a time,
    because the tug skids: its four wheels slip sideways when it turns while driving, so steering
    onto a point near it circles the point instead of reaching it. In order:

    1. at the goal (within `arrive_m`, or abeam of it within `near_m`: driving on would only pass
       it): turn in place to its heading, until it is farther than `near_m` again;
    2. something nearer than `obstacle_m` from base_link (the robot is 2 m long, base_link at its
       middle) within ±`sector_rad` ahead, and nearer than the goal: turn in place to the freer
       side, then drive on for `detour_steps` steps, so that it does not turn straight back into
       the obstacle;
    3. farther than `near_m` and the goal more than `aim_rad` off the nose: turn in place to it;
    4. otherwise drive, slower as the goal nears, steering onto it while farther than `near_m`
       and straight on within it.

    A floor for a learnt policy and a check that a task can be solved, not a planner: a wall
    between the robot and its goal can hold it until the time limit."""

    max_speed: float = 0.8
    """m/s forward at most (`for_space` caps it at the action space's bound)."""
    max_turn: float = 1.5
    """rad/s at most."""
    obstacle_m: float = 1.6
    sector_rad: float = math.radians(30.0)
    arrive_m: float = 0.1
    near_m: float = 0.5
    aim_rad: float = 0.25
    detour_steps: int = 10
    turn_gain: float = 2.0
    speed_gain: float = 0.8
    min_speed: float = 0.15
    extra: tuple[float, ...] = ()
    """Components after (v, ω), as they are (`for_space`: the space's upper bounds)."""
    _detour: int = field(default=0, init=False, repr=False)
    _at_goal: bool = field(default=False, init=False, repr=False)

    @classmethod
    def for_space(cls, space: Any, **kwargs: Any) -> ScriptedPolicy:
        """Its speeds capped at the Box action space's (v, ω) upper bounds; any further components at theirs."""
        high = np.asarray(space.high, dtype=float)
        policy = cls(**{"extra": tuple(float(v) for v in high[2:]), **kwargs})
        policy.max_speed, policy.max_turn = min(policy.max_speed, high[0]), min(policy.max_turn, high[1])
        return policy

    def reset(self, seed: int) -> None:
        """Forgets the last episode's detour and arrival (the seed is not used: the policy draws nothing)."""
        self._detour, self._at_goal = 0, False

    def __call__(self, obs: Observation) -> Action:
        x, y, yaw = (float(v) for v in np.asarray(obs["goal"], dtype=float)[:3])
        distance, bearing = math.hypot(x, y), math.atan2(y, x)
        scan = np.asarray(obs["scan"], dtype=float) if "scan" in obs else np.empty(0)
        near = distance < self.near_m
        self._at_goal = near and (self._at_goal or distance < self.arrive_m or x <= self.arrive_m / 2)
        if self._at_goal:
            return self._action(0.0, self.turn_gain * yaw)
        if self.blocked(scan, distance):
            self._detour = self.detour_steps
            return self._action(0.0, self.max_turn * self._freer_side(scan))
        if self._detour > 0:
            self._detour -= 1
            return self._action(self.min_speed, 0.0)
        if not near and abs(bearing) > self.aim_rad:
            return self._action(0.0, self.turn_gain * bearing)
        speed = min(max(self.speed_gain * x, self.min_speed), self.max_speed)
        return self._action(speed, 0.0 if near else self.turn_gain * bearing)

    def blocked(self, scan: np.ndarray, goal_distance: float) -> bool:
        """Something within `obstacle_m` ahead, and nearer than the goal (a goal by a wall is no obstacle)."""
        if scan.size == 0:
            return False
        ahead = scan[np.abs(bin_angles(scan.size)) <= self.sector_rad]
        ahead = ahead[np.isfinite(ahead)]
        return bool(ahead.size) and float(ahead.min()) < min(self.obstacle_m, goal_distance)

    def _freer_side(self, scan: np.ndarray) -> float:
        """+1 (left) or −1 (right): the side whose nearest return in the front quarter is farther."""
        angles = bin_angles(scan.size)
        ranges = np.where(np.isfinite(scan), scan, np.inf)
        left = ranges[(angles > 0) & (angles <= math.pi / 2)]
        right = ranges[(angles < 0) & (angles >= -math.pi / 2)]
        nearest_left = float(left.min()) if left.size else math.inf
        nearest_right = float(right.min()) if right.size else math.inf
        return 1.0 if nearest_left >= nearest_right else -1.0

    def _action(self, speed: float, turn: float) -> Action:
        v, w = min(max(speed, 0.0), self.max_speed), min(max(turn, -self.max_turn), self.max_turn)
        return np.array([v, w, *self.extra], dtype=np.float32)


def bin_angles(bins: int) -> np.ndarray:
    """The angle of each of `bins` bins over the full circle, bin i centred on −π + i·2π/bins."""
    return -math.pi + np.arange(bins) * (2 * math.pi / bins)


def import_policy(name: str) -> Policy:
    """The callable `module:function` names, imported; PolicyError with one line when it does not import."""
    module_name, _, attribute = name.partition(":")
    if not module_name or not attribute:
        raise PolicyError(f"unknown policy {name!r}: expected {', '.join(BUILT_IN)} or module:function")
    try:
        found: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise PolicyError(f"policy {name!r}: cannot import {module_name!r}: {exc}") from None
    for part in attribute.split("."):
        if not hasattr(found, part):
            raise PolicyError(f"policy {name!r}: {module_name!r} has no {attribute!r}")
        found = getattr(found, part)
    if not callable(found):
        raise PolicyError(f"policy {name!r} is not callable")
    return found


def check_policy(spec: str | Policy) -> None:
    """Raises PolicyError now, in the caller's process, for a name that would fail in every actor."""
    if isinstance(spec, str) and spec not in BUILT_IN:
        import_policy(spec)


def make_policy(spec: str | Policy, action_space: Any) -> Policy:
    """The policy `spec` names, for an environment with `action_space`: `random` and `scripted` are
    built for its bounds; `module:function` is imported; a callable is itself."""
    if not isinstance(spec, str):
        return spec
    if spec == "random":
        return RandomPolicy.for_space(action_space)
    if spec == "scripted":
        return ScriptedPolicy.for_space(action_space)
    return import_policy(spec)
