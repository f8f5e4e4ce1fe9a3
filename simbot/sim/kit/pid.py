"""The PID of Gazebo's joint controllers (gz::math::PID): its SDF gains and its update.

| parameter | meaning | default |
|---|---|---|
| `p_gain`, `i_gain`, `d_gain` | gains | per system |
| `i_max`, `i_min` | bounds of the integral term | 1, −1 |
| `cmd_max`, `cmd_min` | bounds of the output | 1000, −1000 |
| `cmd_offset` | feed-forward added to the output | 0 |

The error is measured minus target, as Gazebo's controllers give it, so the output is
offset − p·e − (integral of i·e) − d·ė.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.description.model import Plugin
from simbot.description.plugin_params import number_param


@dataclass(frozen=True)
class PidGains:
    p: float
    i: float
    d: float
    i_max: float = 1.0
    i_min: float = -1.0
    cmd_max: float = 1000.0
    cmd_min: float = -1000.0
    cmd_offset: float = 0.0

    @staticmethod
    def parse(plugin: Plugin, p: float, i: float, d: float) -> PidGains:
        """The plugin's gains; `p`, `i`, `d` are the system's own defaults."""
        base = PidGains(p, i, d)

        def read(tag: str, default: float) -> float:
            value = number_param(plugin, tag, default=default)
            assert value is not None
            return value

        return PidGains(
            read("p_gain", p), read("i_gain", i), read("d_gain", d),
            read("i_max", base.i_max), read("i_min", base.i_min),
            read("cmd_max", base.cmd_max), read("cmd_min", base.cmd_min), read("cmd_offset", base.cmd_offset),
        )  # fmt: skip


class Pid:
    """One controller's state: the integral and the last error."""

    def __init__(self, gains: PidGains) -> None:
        self.gains = gains
        self._integral = 0.0
        self._last_error: float | None = None

    def update(self, error: float, dt: float) -> float:
        """The command for `error` (measured − target) after `dt` seconds."""
        g = self.gains
        self._integral = min(max(self._integral + g.i * error * dt, g.i_min), g.i_max)
        rate = 0.0 if self._last_error is None or dt <= 0 else (error - self._last_error) / dt
        self._last_error = error
        command = g.cmd_offset - g.p * error - self._integral - g.d * rate
        return min(max(command, g.cmd_min), g.cmd_max) if g.cmd_max >= g.cmd_min else command

    def reset(self) -> None:
        self._integral, self._last_error = 0.0, None
