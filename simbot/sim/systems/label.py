"""Label (Gazebo's `gz::sim::systems::Label`): the class a segmentation or bounding-box camera
gives what it sees.

On a `<visual>`, it labels that visual; on a `<model>` or an `<include>`, every visual of the
model, nested models' included (a visual's own label wins over its model's). Geometry without a
label is background to segmentation cameras and has no box, but it still hides what lies behind it.
It does nothing in the loop: the world's Rendering system reads its `annotation` when the model
enters (`Annotating`, simbot/sim/kit/rendered_sensor.py) and hands it to the render workers.

SDF parameters:

| element | default | meaning |
| --- | --- | --- |
| `<label>` | required | the class, an integer 0..255 |
"""

from __future__ import annotations

from simbot.description.plugin_params import param
from simbot.sim.kit.rendered_sensor import covered
from simbot.sim.loop.system import SystemConfigError, SystemContext
from simbot.sim.render import Annotation

MAX_LABEL = 255


class Label:
    """A label for the visuals it covers; see the module docstring."""

    name = "Label"
    runs_on_visuals = True

    def __init__(self, ctx: SystemContext) -> None:
        self.annotation = Annotation(*covered(ctx, "Label"), label=_label(ctx))


def _label(ctx: SystemContext) -> int:
    assert ctx.plugin is not None
    text = param(ctx.plugin, "label")
    where = f"Label on {ctx.model_name}" + (f" visual {ctx.visual.name}" if ctx.visual else "")
    if text is None:
        raise SystemConfigError(f"{where}: <label> is required (an integer 0..{MAX_LABEL})")
    try:
        label = int(text)
    except ValueError:
        raise SystemConfigError(f"{where}: <label> must be an integer 0..{MAX_LABEL}, got {text!r}") from None
    if not 0 <= label <= MAX_LABEL:
        raise SystemConfigError(f"{where}: <label> must be 0..{MAX_LABEL}, got {label}")
    return label
