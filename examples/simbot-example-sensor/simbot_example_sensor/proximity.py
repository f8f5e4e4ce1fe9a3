"""Proximity (SDF `proximity`): the distance to the first thing straight ahead of the sensor.

One ray along the sensor's +x axis, from `<min>` to `<max>` metres, cast in the physics world each
sample; the sensor's own model is transparent to it (as a lidar's robot is to its lidar).
Published as sensor_msgs/Range on the `<sensor>`'s `<topic>`, else on simbot's default key for
a sensor, `world/<w>/model/<m>/link/<l>/sensor/<s>/range`, stamped with the sim time of the
sample, in the sensor's frame. As REP 117 asks, nothing within `<max>` reads +inf.

SDF parameters (under `<proximity>`; `ProximityParams`):

| element | default | meaning |
| --- | --- | --- |
| `<min>` | 0.02 | metres: the ray starts here (the sensor's blind zone) |
| `<max>` | 4.0 | metres: the ray ends here |
| `<field_of_view>` | 0.05 | radians, the cone the message reports (the ray itself is thin) |
| `<radiation>` | infrared | `infrared` or `ultrasound`, the message's radiation type |
| `<noise>` | none | gaussian noise of the range (m), as gz-sensors' `<noise>` |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from simbot.bus.codec import TYPESTORE
from simbot.bus.messages import header
from simbot.description.model import Sensor
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.transform import quaternion_to_matrix

Range: Any = TYPESTORE.types["sensor_msgs/msg/Range"]
"""sensor_msgs/Range, from the ROS 2 message types simbot's codec knows."""
RADIATION = {"ultrasound": 0, "infrared": 1}
"""sensor_msgs/Range's radiation_type constants by their SDF spelling."""


@dataclass(frozen=True)
class ProximityParams:
    """A proximity sensor's SDF parameters (the table in the module docstring)."""

    min: float = 0.02
    max: float = 4.0
    field_of_view: float = 0.05
    radiation: str = "infrared"
    noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> ProximityParams:
        """Reads `<proximity>`; a value that cannot be used is a one-line error naming the element."""
        element = SdfElement.of(sensor).child_or_empty("proximity")
        near, far = element.number("min", 0.02), element.number("max", 4.0)
        if not 0.0 <= near < far:
            raise element.error("max", f"must be more than <min> ({near}) and <min> at least 0, got {far}")
        radiation = element.text("radiation", "infrared") or "infrared"
        if radiation not in RADIATION:
            raise element.error("radiation", f"expected one of {', '.join(RADIATION)}, got {radiation!r}")
        fov = element.number("field_of_view", 0.05)
        return ProximityParams(near, far, fov, radiation, (element.noise() or Noise()).applied)


class Proximity(FramedSensor):
    """sensor_msgs/Range at the sensor's rate: a `FramedSensor` (simbot's frame, rate, noise and publisher
    for one-reading sensors) that casts one ray each sample."""

    def __init__(self, ctx: SystemContext) -> None:
        self.params = ProximityParams.from_sdf(ctx.require_sensor()[2])
        super().__init__(ctx, (self.params.noise,), "range", Range)

    def distance(self) -> float:
        """Metres from the sensor to the first hit along its +x axis, +inf when nothing is within `<max>`."""
        spec = self.params
        position, orientation = self.physics.frame_pose(*self.where)
        ahead = quaternion_to_matrix(orientation)[:, 0]
        origin = np.asarray(position)
        starts, ends = (origin + ahead * spec.min)[None, :], (origin + ahead * spec.max)[None, :]
        fraction = float(self.physics.cast_rays(starts, ends, blind_to=self.where[0])[0])
        return spec.min + fraction * (spec.max - spec.min) if np.isfinite(fraction) else float("inf")

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        measured = self.distance()
        if np.isfinite(measured):
            (measured,) = self.noise((measured,))
        spec = self.params
        self.publish(
            info,
            Range(
                header=header(info.sim_time_ns, self.frame),
                radiation_type=RADIATION[spec.radiation],
                field_of_view=float(spec.field_of_view),
                min_range=float(spec.min),
                max_range=float(spec.max),
                range=float(measured),
            ),
        )
