"""The tf tree as clients see it: transforms from `tf_static` / `tf` messages, looked up by frame.

A client that needs a sensor's pose in `base_link` (the lidar merger, the camera stitcher) reads
it from the bus like a ROS node reads tf, never from the simulator: so the merger also works on a
recording, or on a real robot's topics. Plain numpy, 4×4 homogeneous matrices.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.transform import quaternion_to_matrix, yaw_of

Matrix = npt.NDArray[np.float64]


def transform_matrix(xyz: Sequence[float], quat_xyzw: Sequence[float]) -> Matrix:
    """The 4×4 matrix that maps points of a frame posed at (xyz, quat) into its parent."""
    if not np.linalg.norm(quat_xyzw) > 0:
        raise ValueError(f"quaternion {tuple(quat_xyzw)} has no rotation (zero norm)")
    matrix = np.eye(4)
    matrix[:3, :3] = quaternion_to_matrix(quat_xyzw)
    matrix[:3, 3] = [float(v) for v in xyz]
    return matrix


def planar_pose(pose: Any) -> tuple[float, float, float]:
    """(x, y, yaw) of a geometry_msgs Pose."""
    o = pose.orientation
    return float(pose.position.x), float(pose.position.y), yaw_of((o.x, o.y, o.z, o.w))


class TransformTree:
    """Parent links from TFMessages; `lookup` chains them. Not thread-safe: feed and query from one thread."""

    def __init__(self) -> None:
        self._parents: dict[str, tuple[str, Matrix]] = {}

    def update(self, tf_message: Any) -> None:
        """Take every transform of a tf2_msgs/TFMessage (a later one of a child replaces the earlier)."""
        for stamped in tf_message.transforms:
            t, r = stamped.transform.translation, stamped.transform.rotation
            child = stamped.child_frame_id.lstrip("/")
            parent = stamped.header.frame_id.lstrip("/")
            self._parents[child] = (parent, transform_matrix((t.x, t.y, t.z), (r.x, r.y, r.z, r.w)))

    @property
    def frames(self) -> set[str]:
        """Every frame named so far, parents and children."""
        return set(self._parents) | {parent for parent, _ in self._parents.values()}

    def _to_root(self, frame: str) -> tuple[str, Matrix]:
        """(root frame, the matrix mapping `frame` into it)."""
        matrix = np.eye(4)
        seen = {frame}
        while frame in self._parents:
            frame, step = self._parents[frame]
            if frame in seen:
                raise ValueError(f"tf has a cycle through {frame!r}")
            seen.add(frame)
            matrix = step @ matrix
        return frame, matrix

    def lookup(self, target: str, source: str) -> Matrix | None:
        """The matrix mapping points in `source` into `target` (the pose of `source` in `target`), or None if unconnected."""
        target_root, target_matrix = self._to_root(target)
        source_root, source_matrix = self._to_root(source)
        if target_root != source_root:
            return None
        return np.linalg.inv(target_matrix) @ source_matrix
