"""Bounding-box camera (SDF `boundingbox_camera`, Gazebo's BoundingBoxCameraSensor): the boxes of
the labelled objects it sees (Gazebo's Label system, simbot/sim/systems/label.py), and its image.

Keys, as Gazebo's: the boxes on `<topic>` (else `world/<w>/model/<m>/link/<l>/sensor/<s>/boundingbox`),
the rgb8 image with the boxes drawn on it in green on `<topic>_image`, CameraInfo beside `<topic>`
(its sibling `camera_info`, as the colour camera's). Boxes are vision_msgs/Detection2DArray
(`3d`: Detection3DArray) as ros_gz_bridge maps Gazebo's AnnotatedAxisAligned2DBox_V and
AnnotatedOriented3DBox_V (simbot/bus/messages/vision.py): class_id the label, score 1.0, 2D boxes in
pixels, 3D boxes in the camera's optical frame. How each kind of box is made, and what it covers:
simbot/sim/render/boxes.py. Stamped and framed as the colour camera (simbot/sim/systems/camera.py),
rendered only while the boxes or the image are subscribed.

SDF parameters: the colour camera's, and

| element | default | meaning |
| --- | --- | --- |
| `<camera><box_type>` | 2d | `2d` or `visible_2d` (also `visible_box_2d`): what is seen of each object; `full_2d` (also `full_box_2d`): its whole projected geometry; `3d`: its oriented box |
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from simbot.bus import messages
from simbot.bus.messages import Box2D, Box3D
from simbot.description.model import Sensor
from simbot.description.poses import Pose
from simbot.description.sensor_params import SdfElement
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.system import SystemContext
from simbot.sim.physics import pose_to_transform
from simbot.sim.render import Frame
from simbot.sim.render.boxes import Corners, Objects, Posed, View, draw_box, draw_segment, visible
from simbot.sim.systems.camera import Camera, Product, _Published
from simbot.transform import Transform, matmul

VISIBLE, FULL, ORIENTED = "visible_2d", "full_2d", "3d"
TYPES = {
    "2d": VISIBLE,
    "visible_2d": VISIBLE,
    "visible_box_2d": VISIBLE,
    "full_2d": FULL,
    "full_box_2d": FULL,
    "3d": ORIENTED,
}
"""`<box_type>` as Gazebo reads it → the kind of box."""
EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
"""The twelve edges of a box whose corners are numbered by their (x, y, z) sides as bits."""


def box_type(sensor: Sensor) -> str:
    camera = SdfElement.of(sensor).child_or_empty("camera")
    text = camera.text("box_type", "2d") or "2d"
    if text not in TYPES:
        raise camera.error("box_type", f"must be one of {', '.join(TYPES)}, got {text!r}")
    return TYPES[text]


class BoundingBoxCamera(Camera):
    """Boxes on `<topic>`, the image with them drawn on `<topic>_image`, CameraInfo beside `<topic>`."""

    products = (Product("image", "color"),)
    kind = "boundingbox"
    published_by_worker = False
    """Its image carries the boxes, worked out from the world's geometry the server holds."""

    def __init__(self, ctx: SystemContext) -> None:
        self.box_type = box_type(ctx.require_sensor()[2])
        super().__init__(ctx)
        self.spec = replace(self.spec, outputs=(*self.spec.outputs, "labels"))
        message = messages.Detection3DArray if self.box_type == ORIENTED else messages.Detection2DArray
        self._boxes = ctx.bus.publisher(ctx.sensor_topic(self.kind), message)
        self._objects = Objects()

    def _advertise(self, bus: SimBus, topic: str, product: Product, output: str) -> _Published:
        """The image beside the boxes' key, as Gazebo names it: `<topic>_image`."""
        return super()._advertise(bus, f"{topic}_{product.key}", replace(product, key=""), output)

    def wanted(self) -> bool:
        return self._boxes.has_subscribers or super().wanted()

    def send(self, frame: Frame) -> None:
        """The boxes, and the image with them drawn."""
        view = View(frame.camera_pose or Transform(), self.spec)
        seen = visible(frame["labels"])
        self._objects.forget(set(frame.bodies))
        image = frame["color"] if "color" in frame else frame["mono"]
        drawn = np.array(image if image.ndim == 3 else np.repeat(image[..., np.newaxis], 3, axis=2))
        if self.box_type == ORIENTED:
            posed = self._objects.posed(frame, view, sorted(seen))
            boxes3 = [_oriented(key[1], placed, view) for key, placed in posed.items()]
            for placed in posed.values():
                _draw_oriented(drawn, placed, view)
            self._put(messages.detection_3d_array(frame.stamp_ns, self.frame_id, boxes3))
        else:
            corners = seen if self.box_type == VISIBLE else self._full(frame, view, seen)
            for extent in corners.values():
                draw_box(drawn, extent)
            boxes2 = [Box2D(label, (c[0], c[1]), (c[2], c[3])) for (_, label), c in sorted(corners.items())]
            self._put(messages.detection_2d_array(frame.stamp_ns, self.frame_id, boxes2))
        (output,) = self.outputs
        if output.publisher.has_subscribers:
            output.publisher.put(messages.image(frame.stamp_ns, self.frame_id, drawn))

    def _put(self, message: Any) -> None:
        if self._boxes.has_subscribers:
            self._boxes.put(message)

    def _full(self, frame: Frame, view: View, seen: dict[tuple[int, int], Corners]) -> dict[tuple[int, int], Corners]:
        """The whole projected extent of each object seen."""
        full = {
            key: view.full(placed.optical) for key, placed in self._objects.posed(frame, view, sorted(seen)).items()
        }
        return {key: extent for key, extent in full.items() if extent is not None}


def _local_box(placed: Posed) -> tuple[np.ndarray, np.ndarray]:
    """(centre, size) of the object's axis-aligned box in its root link's frame."""
    low, high = placed.local.min(axis=0), placed.local.max(axis=0)
    return (low + high) / 2.0, high - low


def _oriented(label: int, placed: Posed, view: View) -> Box3D:
    centre, size = _local_box(placed)
    in_optical = matmul(view.optical, placed.root)
    position = matmul(in_optical[:3, :3], centre) + in_optical[:3, 3]
    rotation = np.eye(4)
    rotation[:3, :3] = in_optical[:3, :3]
    quaternion = pose_to_transform(Pose.from_matrix(rotation)).orientation
    return Box3D(label, tuple(position), quaternion, tuple(size))


def _draw_oriented(image: np.ndarray, placed: Posed, view: View) -> None:
    """The box's twelve edges, when all its corners lie beyond the near clip."""
    centre, size = _local_box(placed)
    signs = np.array([[(i >> axis) & 1 for axis in range(3)] for i in range(8)], dtype=float) - 0.5
    corners = view.to_optical(placed.root, centre + signs * size)
    if (corners[:, 2] < view.near).any():
        return
    uv = view.project(corners)
    for a, b in EDGES:
        draw_segment(image, uv[a], uv[b])
