"""vision_msgs, as ros_gz_bridge writes Gazebo's annotated boxes: a Detection2DArray of axis-aligned
image boxes (AnnotatedAxisAligned2DBox_V) or a Detection3DArray of oriented boxes
(AnnotatedOriented3DBox_V), each detection with one hypothesis: class_id the label as a decimal
string, score 1.0. Each detection carries the array's header (the bridge copies the Gazebo box's
own header, which Gazebo leaves empty)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from simbot.bus.messages.geometry import pose, vector3
from simbot.bus.messages.nav import COVARIANCE_SIZE
from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import (
    BoundingBox2D,
    BoundingBox3D,
    Detection2D,
    Detection2DArray,
    Detection3D,
    Detection3DArray,
    Header,
    ObjectHypothesis,
    ObjectHypothesisWithPose,
    Point2D,
    Pose2D,
    PoseWithCovariance,
)
from simbot.bus.messages.values import Floats


@dataclass(frozen=True)
class Box2D:
    """An axis-aligned box in the image: its label, and its corners in pixels (ROS's pixel-centre
    coordinates: pixel (u, v) is centred at (u, v))."""

    label: int
    min_corner: tuple[float, float]
    max_corner: tuple[float, float]


@dataclass(frozen=True)
class Box3D:
    """An oriented box: its label, centre and orientation (x, y, z, w) in the message's frame, and its size (m)."""

    label: int
    center: Floats
    orientation: Floats
    size: Floats


def _hypothesis(label: int) -> ObjectHypothesisWithPose:
    identity = PoseWithCovariance(
        pose=pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), covariance=np.zeros(COVARIANCE_SIZE)
    )
    return ObjectHypothesisWithPose(hypothesis=ObjectHypothesis(class_id=str(int(label)), score=1.0), pose=identity)


def _detection_2d(stamp: Header, box: Box2D) -> Detection2D:
    (x0, y0), (x1, y1) = box.min_corner, box.max_corner
    center = Pose2D(position=Point2D(x=(x0 + x1) / 2.0, y=(y0 + y1) / 2.0), theta=0.0)
    return Detection2D(
        header=stamp,
        results=[_hypothesis(box.label)],
        bbox=BoundingBox2D(center=center, size_x=float(x1 - x0), size_y=float(y1 - y0)),
        id="",
    )


def detection_2d_array(ns: int, frame: str, boxes: Iterable[Box2D]) -> Detection2DArray:
    """vision_msgs/Detection2DArray: centre and size of each box, in pixels."""
    stamp = header(ns, frame)
    return Detection2DArray(header=stamp, detections=[_detection_2d(stamp, box) for box in boxes])


def _detection_3d(stamp: Header, box: Box3D) -> Detection3D:
    return Detection3D(
        header=stamp,
        results=[_hypothesis(box.label)],
        bbox=BoundingBox3D(center=pose(box.center, box.orientation), size=vector3(*map(float, box.size))),
        id="",
    )


def detection_3d_array(ns: int, frame: str, boxes: Iterable[Box3D]) -> Detection3DArray:
    """vision_msgs/Detection3DArray: each box's pose and size in `frame`."""
    stamp = header(ns, frame)
    return Detection3DArray(header=stamp, detections=[_detection_3d(stamp, box) for box in boxes])
