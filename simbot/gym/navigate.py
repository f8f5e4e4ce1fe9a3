"""simbot/Navigate-v0: drive the tug from a free pose to a goal pose without touching anything.

The start is drawn anywhere free in the world, the goal `goal_distance` metres from it (both with a
uniform heading; with `goal_ahead=True`, straight ahead of the start at its heading: a
curriculum's first stage), from the episode's seed; `reset(options={"start": (x, y, yaw), "goal": (x, y,
yaw)})` sets either instead, and one that is not free is an EnvConfigError naming it. Success: the
robot's model frame within `goal_tolerance` (0.3 m, 0.3 rad) of the goal. docs/learning.md has the
spaces, the reward and the options.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from simbot.description.footprints import Planar
from simbot.description.free_poses import MAX_TRIES, NoFreePose
from simbot.gym.base import Rewards, SimbotEnv, View, env_options
from simbot.gym.errors import EnvConfigError
from simbot.gym.options import parse_pose

RESET_OPTIONS = ("start", "goal")


class NavigateEnv(SimbotEnv):
    """Reach a goal pose; see the module docstring."""

    task = "navigate"

    def __init__(
        self,
        goal_distance: tuple[float, float] = (1.0, 5.0),
        goal_tolerance: tuple[float, float] = (0.3, 0.3),
        goal_ahead: bool = False,
        rewards: Rewards | Mapping[str, float] | None = None,
        **kwargs: Any,
    ) -> None:
        low, high = (float(v) for v in goal_distance)
        if not 0 <= low <= high:
            raise EnvConfigError(f"goal_distance {goal_distance!r}: expected (min, max) with 0 ≤ min ≤ max metres")
        self.goal_distance = (low, high)
        self.goal_tolerance = (float(goal_tolerance[0]), float(goal_tolerance[1]))
        self.goal_ahead = bool(goal_ahead)
        super().__init__(env_options(kwargs), rewards)

    def _draw(self, rng: np.random.Generator, options: Mapping[str, Any]) -> tuple[Planar, Planar]:
        unknown = set(options) - set(RESET_OPTIONS)
        if unknown:
            raise EnvConfigError(
                f"reset options: unknown {', '.join(sorted(unknown))} (known: {', '.join(RESET_OPTIONS)})"
            )
        if self.goal_ahead and "start" not in options:
            start, goal = self._ahead(rng)
            return start, parse_pose(options["goal"], "goal") if "goal" in options else goal
        start = self.places.draw(rng, "start")
        if "start" in options:
            start = parse_pose(options["start"], "start")
            self.places.check(start, "start")
        goal = self.places.draw_near(rng, start, self.goal_distance, "goal")
        if "goal" in options:
            goal = parse_pose(options["goal"], "goal")
            self.places.check(goal, "goal")
        return start, goal

    def _ahead(self, rng: np.random.Generator) -> tuple[Planar, Planar]:
        """A free start, and a free goal straight ahead of it at its heading."""
        for _ in range(MAX_TRIES):
            start = self.places.draw(rng, "start")
            reach = float(rng.uniform(*self.goal_distance))
            goal = (start[0] + reach * math.cos(start[2]), start[1] + reach * math.sin(start[2]), start[2])
            if self.places.blocker(goal) is None:
                return start, goal
        raise NoFreePose(f"no free goal found straight ahead of a start in {MAX_TRIES} draws")

    def _judge(self, view: View) -> tuple[float, bool, dict[str, Any]]:
        reached = view.distance <= self.goal_tolerance[0] and view.heading_error <= self.goal_tolerance[1]
        return 0.0, reached, {}
