"""sensor_msgs of cameras: colour and depth images, their pixels back, and the CameraInfo (plumb_bob)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import CameraInfo, Image, RegionOfInterest
from simbot.bus.messages.values import float_array

IMAGE_ENCODINGS = {3: "rgb8", 1: "mono8"}
"""sensor_msgs/image_encodings by channels of uint8 pixels."""


def image(ns: int, frame: str, pixels: npt.NDArray[np.uint8]) -> Image:
    """sensor_msgs/Image from an H×W×3 (rgb8) or H×W (mono8) uint8 array; the bytes are copied once."""
    if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3):
        raise ValueError(f"image: expected H×W or H×W×3 uint8 pixels, got {pixels.dtype} {pixels.shape}")
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    if channels not in IMAGE_ENCODINGS:
        raise ValueError(f"image: {channels} channels; expected 1 or 3")
    height, width = pixels.shape[:2]
    return Image(
        header=header(ns, frame),
        height=height,
        width=width,
        encoding=IMAGE_ENCODINGS[channels],
        is_bigendian=0,
        step=width * channels,
        data=np.ascontiguousarray(pixels).reshape(-1).copy(),
    )


def depth_image(ns: int, frame: str, depth: npt.NDArray[np.float32]) -> Image:
    """sensor_msgs/Image `32FC1` (REP 118: metres along the optical axis, ±inf out of range) from an H×W float32 array."""
    if depth.dtype != np.float32 or depth.ndim != 2:
        raise ValueError(f"depth image: expected H×W float32, got {depth.dtype} {depth.shape}")
    height, width = depth.shape
    return Image(
        header=header(ns, frame),
        height=height,
        width=width,
        encoding="32FC1",
        is_bigendian=0,
        step=width * 4,
        data=np.ascontiguousarray(depth).reshape(-1).view(np.uint8).copy(),
    )


def depth_pixels(msg: Image) -> npt.NDArray[np.float32]:
    """The H×W float32 metres of a `32FC1` Image (the inverse of `depth_image`)."""
    if msg.encoding != "32FC1":
        raise ValueError(f"encoding {msg.encoding!r} is not 32FC1")
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < width * 4 or data.size < step * height:
        raise ValueError(f"{data.size} bytes with step {step} cannot hold {height} rows of {width} 32FC1 pixels")
    rows = data[: step * height].reshape(height, step)[:, : width * 4]
    return np.ascontiguousarray(rows).view(np.float32).reshape(height, width)


CHANNELS_OF = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
"""The uint8 sensor_msgs/image_encodings a client can read, by their channels."""


def image_pixels(msg: Image) -> npt.NDArray[np.uint8]:
    """The pixels of a sensor_msgs/Image: H×W×C uint8 (H×W for mono8), its row padding (step) dropped.

    The inverse of `image`. ValueError, one line, for an encoding not in CHANNELS_OF or data
    too short for height × step.
    """
    channels = CHANNELS_OF.get(msg.encoding)
    if channels is None:
        raise ValueError(f"encoding {msg.encoding!r} is not one of {', '.join(CHANNELS_OF)}")
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < width * channels or data.size < step * height:
        raise ValueError(
            f"{data.size} bytes with step {step} cannot hold {height} rows of {width} {msg.encoding} pixels"
        )
    rows = data[: step * height].reshape(height, step)[:, : width * channels]
    return rows if channels == 1 else rows.reshape(height, width, channels)


def camera_info(
    ns: int,
    frame: str,
    width: int,
    height: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    d: Sequence[float] = (0.0,) * 5,
) -> CameraInfo:
    """sensor_msgs/CameraInfo of a camera with plumb_bob distortion D = [k1, k2, p1, p2, k3] (none
    by default) and identity rectification; P is K, as for a monocular camera."""
    k = (fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0)
    p = (fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0)
    return CameraInfo(
        header=header(ns, frame),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=float_array(d, "D", 5),
        k=float_array(k, "K", 9),
        r=float_array((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), "R", 9),
        p=float_array(p, "P", 12),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )
