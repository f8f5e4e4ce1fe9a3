"""A camera as its sensor_msgs/CameraInfo states it: image size, K, the lens's distortion model and
D, and the frame its images are stamped in. One type for whoever reads or writes a camera_info:
the dataset layout (simbot/dataset_format.py, written by `simbot dataset` and by a camera's
`<save>`) and the clients that reproject images (clients/camera_model.py, the stitcher)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any


class BadInput(ValueError):
    """An image or camera_info that cannot be used (encoding, size, intrinsics); str() is one line."""


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera's size, focal lengths and principal point (ROS's pixel-centre coordinates),
    its lens, and its frame."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion_model: str = "plumb_bob"
    d: tuple[float, ...] = (0.0,) * 5
    frame_id: str = field(default="", compare=False)
    """Where its images are stamped; not part of what it is (two cameras alike compare equal)."""

    @classmethod
    def from_info(cls, info: Any) -> Intrinsics:
        """The intrinsics a sensor_msgs/CameraInfo states, D as it gives it; BadInput when they
        describe no camera (no pixels, or K without positive finite focal lengths)."""
        k = [float(v) for v in info.k]
        fx, fy, cx, cy = k[0], k[4], k[2], k[5]
        if info.width < 1 or info.height < 1:
            raise BadInput(f"camera_info size {info.width}×{info.height}")
        if not (fx > 0 and fy > 0 and all(math.isfinite(v) for v in (fx, fy, cx, cy))):
            raise BadInput(f"camera_info K has fx {fx}, fy {fy}, cx {cx}, cy {cy}")
        d = tuple(float(v) for v in info.d)
        frame = str(info.header.frame_id).lstrip("/")
        return cls(int(info.width), int(info.height), fx, fy, cx, cy, str(info.distortion_model), d, frame)

    @property
    def plumb_bob(self) -> bool:
        """It bends nothing (D all zero, of any model), or as plumb_bob's five finite coefficients:
        what OpenCV's own model undoes."""
        finite = all(map(math.isfinite, self.d))
        return finite and (not any(self.d) or (self.distortion_model == "plumb_bob" and len(self.d) == 5))

    def to_json(self) -> dict[str, Any]:
        return {
            "width": self.width,
            "height": self.height,
            "K": [[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]],
            "distortion_model": self.distortion_model,
            "D": list(self.d),
        }
