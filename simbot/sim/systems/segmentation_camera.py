"""Segmentation camera (SDF `segmentation`, Gazebo's SegmentationCameraSensor): what each pixel shows,
by the label Gazebo's Label system (simbot/sim/systems/label.py) gives the visual there.

Two sensor_msgs/Image (rgb8) under `<topic>` (else Gazebo's default
`world/<w>/model/<m>/link/<l>/sensor/<s>/segmentation`): `<topic>/labels_map` and
`<topic>/colored_map`, laid out as simbot/sim/render/segmentation.py says (semantic: the label in
each pixel; instance / panoptic: the label and the object's 16-bit instance number; the sky and
unlabelled geometry are background, 0 and black). CameraInfo is `<topic>/camera_info`, as Gazebo's
segmentation sensor names it. Stamped and framed as the colour camera (simbot/sim/systems/camera.py),
rendered only while a map is subscribed.

SDF parameters: the colour camera's (`<horizontal_fov>`, `<image>` size, `<clip>`, `<update_rate>`;
`<image><format>`, `<noise>` and `<distortion>` do not apply to labels and are ignored), and

| element | default | meaning |
| --- | --- | --- |
| `<camera><segmentation_type>` (or `<segmentation_type>` under `<sensor>`) | semantic | semantic, instance or panoptic (instance and panoptic are one, as in Gazebo) |
"""

from __future__ import annotations

from simbot.description.model import Sensor
from simbot.description.sensor_params import SdfElement
from simbot.sim.loop.system import SystemContext
from simbot.sim.render.segmentation import OUTPUTS, PANOPTIC, SEMANTIC
from simbot.sim.systems.camera import Camera, Product

TYPES = {"semantic": SEMANTIC, "instance": PANOPTIC, "panoptic": PANOPTIC}
"""`<segmentation_type>` (any case, as Gazebo reads it) → the outputs' family."""


def segmentation_type(sensor: Sensor) -> str:
    """SEMANTIC or PANOPTIC from `<camera><segmentation_type>`, else the sensor's own, else semantic."""
    element = SdfElement.of(sensor)
    camera = element.child_or_empty("camera")
    where, text = (camera, camera.text("segmentation_type"))
    if text is None:
        where, text = (element, element.text("segmentation_type"))
    if text is None:
        return SEMANTIC
    if text.lower() not in TYPES:
        raise where.error("segmentation_type", f"must be semantic, instance or panoptic, got {text!r}")
    return TYPES[text.lower()]


class SegmentationCamera(Camera):
    """labels_map and colored_map (rgb8) under `<topic>`, CameraInfo beside them."""

    kind = "segmentation"

    def __init__(self, ctx: SystemContext) -> None:
        labels, colors = OUTPUTS[segmentation_type(ctx.require_sensor()[2])]
        self.products = (Product("labels_map", labels), Product("colored_map", colors))
        super().__init__(ctx)

    def info_key(self, topic: str) -> str:
        return f"{topic}/camera_info"
