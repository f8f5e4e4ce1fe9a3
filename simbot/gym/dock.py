"""simbot/Dock-v0: drive under the trolley and attach to it.

The trolley stands where the world puts it (the warehouse's at (1, 0.2); a world without one gets
simbot's trolley at the origin); the tug starts at a free pose `start_distance` metres from it,
heading anywhere, drawn from the episode's seed (`reset(options={"start": (x, y, yaw)})` sets it).

Attaching follows the docking client's rule (clients/dock.py): the robot's and the trolley's
origins within `dock_distance` (0.55 m) in the plane at each of its checks over the last
`DOCK_HOLD_S` (the client checks three times 0.2 s apart; here at the end of every step in that
span). The action is (v, ω, attach): an attach value above 0.5 asks for it; the environment puts
`attach` before the step when the rule holds, and counts (and, by `rewards.refused_attach`,
penalises) a request when it does not. With `auto_attach=True` the action is (v, ω) and the
environment asks whenever the rule holds. Success, which ends the episode: the joint's state
(`detachable_joint/state`) reads `attached` after the step.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from simbot.bus import messages
from simbot.description.footprints import Planar
from simbot.gym.base import POSE, Rewards, SimbotEnv, View, env_options
from simbot.gym.errors import EnvConfigError
from simbot.gym.observe import Source, planar
from simbot.gym.options import parse_pose
from simbot.gym.serve import TROLLEY

DOCK_HOLD_S = 0.4
"""How long the robot must have been near (the client's three checks 0.2 s apart span 0.4 s)."""
ATTACH_WAIT_S = 2.0
"""How long after the step an attach may take to be reported (it is normally in before the clock)."""


class DockEnv(SimbotEnv):
    """Dock under the trolley; see the module docstring."""

    task = "dock"

    def __init__(
        self,
        start_distance: tuple[float, float] = (1.5, 4.0),
        dock_distance: float = 0.55,
        auto_attach: bool = False,
        rewards: Rewards | Mapping[str, float] | None = None,
        **kwargs: Any,
    ) -> None:
        low, high = (float(v) for v in start_distance)
        if not 0 <= low <= high:
            raise EnvConfigError(f"start_distance {start_distance!r}: expected (min, max) with 0 ≤ min ≤ max metres")
        if not dock_distance > 0:
            raise EnvConfigError(f"dock_distance {dock_distance!r}: must be > 0 m")
        self.start_distance = (low, high)
        self.dock_distance = float(dock_distance)
        self.auto_attach = bool(auto_attach)
        options = env_options(kwargs)
        self._checks = math.ceil(DOCK_HOLD_S / options.control_period - 1e-9) + 1
        self._near: deque[bool] = deque(maxlen=self._checks)
        self._refused = 0
        self._asked = self._refused_now = False
        super().__init__(options, rewards)

    # --- the task -------------------------------------------------------------------------------

    def _check_robot(self) -> None:
        if self.robot.attach_topic is None or self.robot.attach_state_topic is None:
            raise EnvConfigError(f"robot {self.robot.source}: no DetachableJoint plugin to attach with")

    def _extra_sources(self) -> dict[str, Source]:
        return {TROLLEY: (f"model/{TROLLEY}/pose", POSE)}

    def _action_space(self) -> spaces.Box:
        linear, angular = self.limits
        if self.auto_attach:
            return super()._action_space()
        return spaces.Box(np.array([-linear, -angular, 0.0], np.float32), np.array([linear, angular, 1.0], np.float32))

    def _draw(self, rng: np.random.Generator, options: Mapping[str, Any]) -> tuple[Planar, Planar]:
        unknown = set(options) - {"start"}
        if unknown:
            raise EnvConfigError(f"reset options: unknown {', '.join(sorted(unknown))} (known: start)")
        trolley = self._trolley_start()
        start = self.places.draw_near(rng, trolley, self.start_distance, "start")
        if "start" in options:
            start = parse_pose(options["start"], "start")
            self.places.check(start, "start")
        return start, trolley

    def _trolley_start(self) -> Planar:
        """Where the trolley stands after a world reset: its pose in the world's file (or its own, or
        where the episode's variant moved it)."""
        model = next(m for m in self.layout.models if m.name == TROLLEY)
        return (float(model.pose.xyz[0]), float(model.pose.xyz[1]), float(model.pose.rpy[2]))

    def _target(self, msgs: Mapping[str, Any]) -> Planar:
        return planar(msgs[TROLLEY])

    def _episode_started(self) -> None:
        self._near.clear()
        self._refused = 0
        self._asked = self._refused_now = False

    def _commands(self, action: npt.NDArray[np.float64]) -> list[tuple[str, Any]]:
        commands = super()._commands(action)
        wants = self.auto_attach or float(action[2]) > 0.5
        rule = len(self._near) == self._checks and all(self._near)
        self._asked = wants and rule
        self._refused_now = wants and not rule and not self.auto_attach
        self._refused += int(self._refused_now)
        if self._asked:
            assert self.robot.attach_topic is not None
            commands.append((self.robot.attach_topic, messages.empty()))
            self._observer.expect_attach_state()  # success is an `attached` said after this request
        return commands

    def _judge(self, view: View) -> tuple[float, bool, dict[str, Any]]:
        attached = False
        if self._asked:
            state = self._observer.attach_state("attached", self._session.check, ATTACH_WAIT_S)
            attached = state == "attached"
        self._near.append(view.distance <= self.dock_distance)
        reward = -self.rewards.refused_attach if self._refused_now else 0.0
        return reward, attached, {"attached": attached, "refused_attach": self._refused}
