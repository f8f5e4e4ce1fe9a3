"""Thermal (Gazebo's `gz::sim::systems::Thermal`): the temperature a thermal camera sees of a
visual or a model.

On a `<visual>`, that visual; on a `<model>` or an `<include>`, every visual of the model (a
visual's own wins). Geometry no Thermal system covers shows the world's `<atmosphere>`
temperature at its height (temperature + temperature_gradient × z). Like `Label` it does nothing in
the loop: the Rendering system reads its `annotation` when the model enters.

SDF parameters:

| element | default | meaning |
| --- | --- | --- |
| `<temperature>` | required | kelvin, > 0 |
| `<heat_signature>`, `<min_temp>`, `<max_temp>` | none, the atmosphere's temperature | a texture whose grey maps min..max (K; Gazebo's defaults): not drawn; the visual shows the hotter bound (a warning says so) |

A heat signature is not drawn because drawing it would take a texture per annotated visual in the
OpenGL renderer's annotation pass, whose static geometry is batched by surface alone (and
TinyRenderer has one temperature per link).
"""

from __future__ import annotations

import logging

from simbot.description.plugin_params import number_param, param
from simbot.sim.kit.rendered_sensor import covered
from simbot.sim.loop.system import SystemConfigError, SystemContext
from simbot.sim.render import Annotation

log = logging.getLogger(__name__)


class Thermal:
    """A temperature for the visuals it covers; see the module docstring."""

    name = "Thermal"
    runs_on_visuals = True

    def __init__(self, ctx: SystemContext) -> None:
        link, visual = covered(ctx, "Thermal")
        self.annotation = Annotation(link, visual, temperature=_temperature(ctx))


def _temperature(ctx: SystemContext) -> float:
    plugin = ctx.plugin
    assert plugin is not None
    where = f"Thermal on {ctx.model_name}" + (f" visual {ctx.visual.name}" if ctx.visual else "")
    if param(plugin, "heat_signature") is not None:
        ambient = ctx.world.atmosphere.temperature
        bounds = [
            number_param(plugin, tag, default=ambient, positive=True) or ambient for tag in ("min_temp", "max_temp")
        ]
        hottest = max(bounds)  # Gazebo swaps a <min_temp> above <max_temp>
        log.warning("%s: <heat_signature> is not drawn; the visual shows its hottest, %.2f K", where, hottest)
        return hottest
    temperature = number_param(plugin, "temperature", positive=True)
    if temperature is None:
        raise SystemConfigError(f"{where}: <temperature> is required (kelvin)")
    return temperature
