"""sensor_msgs/PointCloud2 in the two layouts simbot publishes (an RGB-D camera's organised cloud,
a 3-D lidar's as Gazebo packs it), and each one's array back."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import PointCloud2, PointField
from simbot.bus.messages.values import Floats

POINT_FIELDS = ("x", "y", "z", "rgb")
"""An organised cloud's fields, float32 each; rgb packs 0x00RRGGBB into the float's bits (PCL's convention)."""


def point_cloud(ns: int, frame: str, points: npt.NDArray[np.float32]) -> PointCloud2:
    """sensor_msgs/PointCloud2, organised (H×W), from H×W×4 float32 x y z rgb; NaN marks no point."""
    if points.dtype != np.float32 or points.ndim != 3 or points.shape[2] != len(POINT_FIELDS):
        raise ValueError(f"point cloud: expected H×W×4 float32, got {points.dtype} {points.shape}")
    height, width = points.shape[:2]
    fields = [
        PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, name in enumerate(POINT_FIELDS)
    ]
    return PointCloud2(
        header=header(ns, frame),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=16,
        row_step=16 * width,
        data=np.ascontiguousarray(points).reshape(-1).view(np.uint8).copy(),
        is_dense=False,
    )


def point_cloud_array(msg: PointCloud2) -> npt.NDArray[np.float32]:
    """H×W×4 float32 x y z rgb of a cloud `point_cloud` made (the inverse of `point_cloud`)."""
    names = tuple(f.name for f in msg.fields)
    if names != POINT_FIELDS or int(msg.point_step) != 16:
        raise ValueError(
            f"fields {names} with point step {msg.point_step}: expected {POINT_FIELDS} float32 at 16 bytes"
        )
    data = np.asarray(msg.data, dtype=np.uint8)
    return np.ascontiguousarray(data).view(np.float32).reshape(int(msg.height), int(msg.width), 4)


LIDAR_POINT_FIELDS = (
    ("x", 0, PointField.FLOAT32),
    ("y", 4, PointField.FLOAT32),
    ("z", 8, PointField.FLOAT32),
    ("intensity", 12, PointField.FLOAT32),
    ("ring", 16, PointField.UINT16),
)
"""A lidar's cloud as Gazebo's gpu_lidar packs it: x y z intensity float32, ring uint16, 18 bytes a point, unaligned."""
LIDAR_POINT_DTYPE = np.dtype(
    {"names": ["x", "y", "z", "intensity", "ring"], "formats": ["<f4"] * 4 + ["<u2"], "offsets": [0, 4, 8, 12, 16]}
)


def lidar_points(ns: int, frame: str, xyz: npt.NDArray[np.floating[Any]], intensity: Floats = ()) -> PointCloud2:
    """sensor_msgs/PointCloud2 of a 3-D lidar, organised V×H (a row per vertical angle, its ring number);
    NaN coordinates where a ray returned nothing; intensity 0 where none is given."""
    if xyz.ndim != 3 or xyz.shape[2] != 3:
        raise ValueError(f"lidar points: expected V×H×3 coordinates, got {xyz.shape}")
    rows, columns = xyz.shape[:2]
    points = np.zeros((rows, columns), dtype=LIDAR_POINT_DTYPE)
    for i, axis in enumerate("xyz"):
        points[axis] = xyz[:, :, i]
    if len(intensity):
        points["intensity"] = np.asarray(intensity, dtype=np.float32).reshape(rows, columns)
    points["ring"] = np.arange(rows, dtype=np.uint16)[:, None]
    return PointCloud2(
        header=header(ns, frame),
        height=rows,
        width=columns,
        fields=[PointField(name=n, offset=o, datatype=t, count=1) for n, o, t in LIDAR_POINT_FIELDS],
        is_bigendian=False,
        point_step=LIDAR_POINT_DTYPE.itemsize,
        row_step=LIDAR_POINT_DTYPE.itemsize * columns,
        data=points.reshape(-1).view(np.uint8).copy(),
        is_dense=bool(np.isfinite(xyz).all()),
    )


def lidar_points_array(msg: PointCloud2) -> npt.NDArray[np.void]:
    """The V×H structured array (x, y, z, intensity, ring) of a cloud `lidar_points` made (its inverse)."""
    fields = tuple((f.name, int(f.offset), int(f.datatype)) for f in msg.fields)
    if fields != LIDAR_POINT_FIELDS or int(msg.point_step) != LIDAR_POINT_DTYPE.itemsize:
        raise ValueError(f"fields {fields} with point step {msg.point_step}: not a lidar cloud {LIDAR_POINT_FIELDS}")
    data = np.ascontiguousarray(np.asarray(msg.data, dtype=np.uint8))
    return data.view(LIDAR_POINT_DTYPE).reshape(int(msg.height), int(msg.width))
