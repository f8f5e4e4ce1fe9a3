"""A drive's command from its key to what it applies: the one way DiffDrive, AckermannSteering and
MecanumDrive take theirs, so that the limits, the idle step and reset cannot drift apart again.

Gazebo's drives, all three: the last valid message is the target; every step each component is
ramped at its acceleration limits and then clamped to its velocity limits (gz-math's
SpeedLimiter order; jerk limits are not supported), the zero before the first command included.
What simbot adds is the idle step: a drive whose command holds (no message, and the last step
changed nothing) applies nothing, since PyBullet's velocity motors and the kinematic stepper keep
the last command; most of a fleet idles most steps. A reset stands the drive at zero: the next
step applies the limited zero, as the first step does.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

from simbot.description.drive_params import Limits
from simbot.sim.loop.bus_view import Doorbell, Input

log = logging.getLogger(__name__)

Command = tuple[float, ...]
"""A drive's command, one float per component (v and ω; vx, vy and ω; a steering angle)."""


class CommandPipeline:
    """Drains a drive's input, limits its command per component, and says what to apply each step."""

    def __init__(self, commands: Input, components: Callable[[Any], Command], limits: Sequence[Limits]) -> None:
        """`components` reads a message's command; `limits[i]` bounds component i."""
        self._commands, self._components, self._limits = commands, components, tuple(limits)
        self._target = self._current = (0.0,) * len(self._limits)
        self._applied: Command | None = None
        self._holds = False

    @property
    def current(self) -> Command:
        """The command as limited at the last step."""
        return self._current

    @property
    def idle(self) -> bool:
        """Whether the next step would apply nothing: the command holds and no message waits."""
        return self._holds and not self._commands.pending

    def rings(self, bell: Doorbell, owner: Any) -> None:
        """Each command that comes rings `bell` for `owner` (the drive): its batch steps it then."""
        self._commands.rings(bell, owner)

    def step(self, dt: float) -> Command | None:
        """The command to apply before a physics step of `dt` seconds; None where the one applied holds."""
        messages = self._commands.drain()
        if messages:
            self._target = self._components(messages[-1])
            self._log_clamped()
        elif self._holds:
            return None
        limited = tuple(
            limits.clamp(limits.ramp(now, goal, dt))
            for limits, now, goal in zip(self._limits, self._current, self._target)
        )
        self._holds = limited == self._current  # a fixed point of the limits: the next step changes nothing
        self._current = limited
        if limited == self._applied:
            return None
        self._applied = limited
        return limited

    def reset(self) -> None:
        """Target and command back to zero; the next step applies the limited zero."""
        self._target = self._current = (0.0,) * len(self._limits)
        self._applied, self._holds = None, False

    def _log_clamped(self) -> None:
        if any(limits.clamp(goal) != goal for limits, goal in zip(self._limits, self._target)):
            log.debug("%s: command %s beyond the velocity limits; clamped", self._commands.key, self._target)
