"""The tf tree as clients see it: transforms from `tf_static` / `tf` messages, looked up by frame.

A client that needs a sensor's pose in `base_link` (the lidar merger, the camera stitcher) reads
it from the bus like a ROS node reads tf, never from the simulator: so the merger also works on a
recording, or on a real robot's topics. Plain numpy, 4×4 homogeneous matrices.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simbot.transform import Matrix, Transform, matmul, norm, rigid_inverse, yaw_of


def _transform_of(msg: Any) -> Transform:
    """The Transform of a geometry_msgs/Transform; ValueError for a zero quaternion, which is no rotation
    (a malformed tf message must not turn every pose looked up through it into NaN)."""
    t, r = msg.translation, msg.rotation
    quat = (r.x, r.y, r.z, r.w)
    if not norm(quat) > 0:
        raise ValueError(f"quaternion {quat} has no rotation (zero norm)")
    return Transform.of((t.x, t.y, t.z), quat)


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
            child = stamped.child_frame_id.lstrip("/")
            parent = stamped.header.frame_id.lstrip("/")
            self._parents[child] = (parent, _transform_of(stamped.transform).matrix())

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
            matrix = matmul(step, matrix)
        return frame, matrix

    def rooted(self, frame: str) -> tuple[str, Matrix]:
        """(the root of `frame`'s tree, the pose of `frame` in it): a robot's frames from its root link."""
        return self._to_root(frame)

    def lookup(self, target: str, source: str) -> Matrix | None:
        """The matrix mapping points in `source` into `target` (the pose of `source` in `target`), or None if unconnected."""
        target_root, target_matrix = self._to_root(target)
        source_root, source_matrix = self._to_root(source)
        if target_root != source_root:
            return None
        return matmul(rigid_inverse(target_matrix), source_matrix)
