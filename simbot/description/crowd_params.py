"""SocialForce's parameters (a person who walks its route and gives way): the social-force model's
`Crowd`, read from the `<plugin>` over its defaults (`read_crowd`) and checked against each
parameter's range. The table of them, with their sources: simbot/sim/systems/crowd.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from simbot.description.errors import SystemConfigError
from simbot.description.model import Plugin
from simbot.description.plugin_params import number_param


@dataclass(frozen=True)
class Crowd:
    """The social-force model's parameters (the SDF elements of the same names; their table, sources
    and meaning: simbot/sim/systems/crowd.py), as simbot.sim.kit.social_force uses them."""

    desired_speed: float = 1.34
    relaxation_time: float = 0.5
    radius: float = 0.3
    max_speed_factor: float = 1.3
    people_strength: float = 2.1
    people_range: float = 0.3
    anisotropy: float = 0.5
    look_ahead: float = 2.0
    obstacle_strength: float = 10.0
    obstacle_range: float = 0.2
    obstacle_cutoff: float = 0.5
    robot_strength: float = 2.1
    robot_range: float = 0.4
    noise: float = 0.05
    turn_rate: float = math.pi
    waypoint_tolerance: float = 0.3
    update_rate: float = 50.0

    @property
    def reach(self) -> float:
        """Metres beyond which a person's or a robot's repulsion is under 10⁻⁴ of its strength: what is
        farther is left out."""
        return 2 * self.radius + 9.3 * max(self.people_range, self.robot_range)

    @property
    def obstacle_reach(self) -> float:
        """Metres from a person's centre beyond which an obstacle exerts nothing (or under 10⁻⁴ of its strength)."""
        return self.radius + min(self.obstacle_cutoff, 9.3 * self.obstacle_range)


FALLBACK_SPEED = 1.34
"""m/s: v0 where neither the plugin nor a moving script gives one (Helbing & Molnár 1995)."""
POSITIVE = (0.0, False, math.inf)
NOT_NEGATIVE = (0.0, True, math.inf)
RANGES: dict[str, tuple[float, bool, float]] = {
    **dict.fromkeys(("desired_speed", "relaxation_time", "radius", "people_range", "obstacle_range"), POSITIVE),
    **dict.fromkeys(("obstacle_cutoff", "robot_range", "turn_rate", "waypoint_tolerance", "update_rate"), POSITIVE),
    **dict.fromkeys(("people_strength", "look_ahead", "obstacle_strength", "robot_strength", "noise"), NOT_NEGATIVE),
    "max_speed_factor": (1.0, True, math.inf),
    "anisotropy": (0.0, True, 1.0),
}
"""Each parameter's lower bound, whether the bound itself is allowed, and its upper bound (allowed)."""


def read_crowd(plugin: Plugin, actor: str, script_speed: float | None) -> Crowd:
    """The plugin's parameters over the defaults; SystemConfigError naming the actor and the element
    for one that is not a number or out of range."""
    defaults = replace(Crowd(), desired_speed=script_speed or FALLBACK_SPEED)
    values: dict[str, float] = {}
    for item in fields(Crowd):
        default = getattr(defaults, item.name)
        try:
            value = number_param(plugin, item.name, default=default)
        except SystemConfigError as exc:
            raise SystemConfigError(f"actor {actor!r}: {exc}; it walks its script") from None
        assert value is not None
        low, inclusive, high = RANGES[item.name]
        if not (value >= low if inclusive else value > low) or value > high:
            rule = f"{'at least' if inclusive else 'more than'} {low:g}" + (
                f" and at most {high:g}" if high < math.inf else ""
            )
            raise SystemConfigError(
                f"{plugin.name}: actor {actor!r}: <{item.name}> must be {rule}, got {value:g}; it walks its script"
            )
        values[item.name] = value
    return Crowd(**values)
