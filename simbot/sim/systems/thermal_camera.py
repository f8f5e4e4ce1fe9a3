"""Thermal camera (SDF `thermal`, also `thermal_camera`): Gazebo's ThermalCameraSensor, the
temperature of what each pixel sees as a `mono16` (L16) or `mono8` (L8) sensor_msgs/Image.

The same camera as `camera` (its `<camera>` elements, its image on `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/image`, camera_info beside it under the same stamp),
rendering the `temperature` buffer (simbot/sim/render/outputs.py) and counting it
(simbot/sim/render/thermal_counts.py): count = rint(clamp(T, min_temp, max_temp) / resolution). What it
sees:

- a visual (or a model) with Gazebo's Thermal system (simbot/sim/systems/thermal.py): its `<temperature>`;
- geometry without one: the world's `<atmosphere>` temperature at its height, `<temperature>` +
  `<temperature_gradient>` × z (the OpenGL renderer, per pixel; TinyRenderer at z = 0). Gazebo
  gives such geometry its ambient temperature varied by its unlit colour's grey over an ambient
  band (|gradient| × the view's height at the far clip), ambient − band/2 for black up to
  ambient + band/2 for white; simbot uses the height instead of the colour;
- the sky (nothing drawn): ambient − band/2, as in Gazebo, whose sky is its black clear colour.
  The band is gz-sim's: |gradient| × 2·tan(vfov/2)·far, its vfov = 2·atan(tan(hfov/2)/aspect)
  with the aspect width ÷ height in whole numbers (so a 4:3 image takes vfov = hfov). With no
  gradient the sky reads the atmosphere's temperature.

SDF parameters (besides the camera's):

| element | default | meaning |
| --- | --- | --- |
| `<camera><image><format>` | L16 | L16 / L_INT16 (mono16) or L8 / L_INT8 (mono8) |
| `<plugin name="gz::sim::systems::ThermalSensor">` `<resolution>` | 0.01 (L16), 3.0 (L8) | K a count, > 0 |
| same plugin, `<min_temp>`, `<max_temp>` | unbounded | K; readings are clamped to min..max; one alone: the other 0 / unbounded |

As in Gazebo, `<distortion>` and `<noise>` are not applied to a thermal image (camera_info says
no distortion). A bad parameter (another format, min_temp >= max_temp, resolution <= 0) is one
error line naming the sensor and the element; the sensor is then off and the rest of the world
runs. (Gazebo falls back to L16 for another format and to its defaults for the others.)
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Atmosphere, Param, Sensor
from simbot.description.sensor_params import SdfElement
from simbot.sim.loop.system import SystemContext
from simbot.sim.render.lens import Distortion
from simbot.sim.render.specs import CameraSpec
from simbot.sim.render.thermal_counts import DEFAULT_RESOLUTION, ThermalScale, ThermalSpec
from simbot.sim.systems.camera import Camera, Message, Product

log = logging.getLogger(__name__)

FORMATS = {"L16": 16, "L_INT16": 16, "L8": 8, "L_INT8": 8}
"""SDF image formats of a thermal camera, by bits a pixel."""
PLUGIN = "ThermalSensor"
"""The last part of the name of the `<plugin>` inside the `<sensor>` that sets its range and resolution."""


def mono16_image(ns: int, frame: str, counts: npt.NDArray[np.uint16]) -> Any:
    """sensor_msgs/Image `mono16` (little-endian) from an H×W uint16 array."""
    height, width = counts.shape
    return messages.Image(
        header=messages.header(ns, frame),
        height=height,
        width=width,
        encoding="mono16",
        is_bigendian=0,
        step=width * 2,
        data=np.ascontiguousarray(counts, dtype="<u2").reshape(-1).view(np.uint8).copy(),
    )


PRODUCTS = {
    16: (Product("", "thermal16", Message(messages.Image, mono16_image)),),
    8: (Product("", "thermal8"),),
}


@dataclass(frozen=True)
class ThermalParams:
    """A thermal camera's own SDF parameters (the table in the module docstring), checked."""

    bits: int
    resolution: float
    min_temp: float
    max_temp: float

    @staticmethod
    def from_sdf(sensor: Sensor) -> ThermalParams:
        image = SdfElement.of(sensor).child_or_empty("camera").child_or_empty("image")
        stated = image.text("format", "L16") or "L16"
        if stated not in FORMATS:
            raise image.error("format", f"{stated!r} is no thermal format; use one of {', '.join(FORMATS)}")
        bits = FORMATS[stated]
        plugin = _plugin(sensor)
        resolution = plugin.number("resolution", DEFAULT_RESOLUTION[bits])
        if resolution <= 0.0:
            raise plugin.error("resolution", f"must be > 0 K a count, got {resolution}")
        ranged = plugin.text("min_temp") is not None or plugin.text("max_temp") is not None
        low, high = (0.0, math.inf) if ranged else (-math.inf, math.inf)
        min_temp, max_temp = plugin.number("min_temp", low), plugin.number("max_temp", high)
        if min_temp >= max_temp:
            raise plugin.error("min_temp", f"must be below <max_temp>, got {min_temp} and {max_temp}")
        return ThermalParams(bits, resolution, min_temp, max_temp)

    def scale(self, spec: CameraSpec, atmosphere: Atmosphere) -> ThermalScale:
        band = ambient_band(atmosphere.temperature_gradient, spec.hfov, spec.width, spec.height, spec.far)
        return ThermalScale(self.resolution, self.min_temp, self.max_temp, atmosphere.temperature - band / 2.0)


def _plugin(sensor: Sensor) -> SdfElement:
    """The sensor's ThermalSensor plugin's elements; none (every default) without one."""
    found = next((p for p in sensor.params if p.tag == "plugin" and _names(p).endswith(PLUGIN)), None)
    return SdfElement(sensor.name, found.children if found else (), ("plugin",))


def _names(plugin: Param) -> str:
    return dict(plugin.attrs).get("name", "").strip()


def ambient_band(gradient: float, hfov: float, width: int, height: int, far: float) -> float:
    """gz-sim's ambient temperature range of a thermal camera (K): |gradient| over the height its
    view spans at the far clip, the aspect ratio divided in whole numbers as gz-sim divides it."""
    aspect = width // height
    vfov = 2.0 * math.atan2(math.tan(hfov / 2.0), aspect)
    return abs(gradient * math.tan(vfov / 2.0) * far * 2.0)


class ThermalCamera(Camera):
    """sensor_msgs/Image (mono16 or mono8 counts) on `<topic>` and CameraInfo beside it."""

    def __init__(self, ctx: SystemContext) -> None:
        _, _, sensor = ctx.require_sensor()
        params = ThermalParams.from_sdf(sensor)
        self.products = PRODUCTS[params.bits]
        super().__init__(ctx)
        pinhole = dataclasses.replace(self.spec, distortion=Distortion(), noise_stddev=0.0)
        self.spec = ThermalSpec.of(pinhole, params.scale(pinhole, ctx.world.atmosphere))
