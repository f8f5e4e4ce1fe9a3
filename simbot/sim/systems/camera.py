"""Camera (SDF `camera`): images rendered by the rendering system, stamped with the sim time they show.

The world's one `Rendering` system (simbot/sim/systems/rendering.py) finds the camera by its
`RenderedSensor` contract (simbot/sim/render/contract.py), schedules it and renders it in worker
processes. This module says what a camera renders
and how a frame becomes messages; `depth_camera` and `rgbd_camera` are the same camera with
other outputs.

Images are stamped in the camera's optical frame (z forward, x right, y down; tf_static places
it), as ROS expects of camera data. Its image key is `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/image` (`.../depth_image` for a depth camera). Every
frame goes out with its `camera_info` under the same stamp (image_transport's CameraSubscriber,
RViz and exact-time synchronisers pair them by stamp); while only camera_info is subscribed, it
goes out at the camera's rate without rendering. camera_info holds the true pinhole intrinsics: fx = fy = (w/2)/tan(hfov/2), principal
point at the image centre ((w−1)/2, (h−1)/2 in ROS's pixel-centre coordinates, where the
symmetric frustum puts it). Its key is the image key's sibling, as Gazebo names it: the last
segment replaced by `camera_info` (`a/b/image` → `a/b/camera_info`), or `<key>/camera_info` for a
key of one segment (`camera_front` → `camera_front/camera_info`).

SDF parameters (under `<camera>`; `CameraParams`):

| element | default | meaning |
| --- | --- | --- |
| `<horizontal_fov>` | 1.047 | radians, in (0, π) |
| `<image><width>`, `<height>` | 320, 240 | pixels, 1..8192 (`--camera-size` overrides) |
| `<image><format>` | R8G8B8 | R8G8B8 / RGB_INT8 (rgb8) or L8 / L_INT8 (mono8); depth cameras ignore it |
| `<clip><near>`, `<far>` | 0.1, 100 | metres, 0 < near < far |
| `<noise>` (`type`, `stddev`) | none | gaussian pixel noise, fraction of full scale |
| `<update_rate>` (of the `<sensor>`) | 30 | frames per second (`--camera-rate` overrides) |

Command-line parameters (`RunOptions.overrides`): `camera.size` ((width, height)), `camera.rate` (Hz).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from simbot.bus import Publisher, messages
from simbot.bus.frames import optical_frame
from simbot.description.model import Sensor
from simbot.sim.bus_view import SimBus
from simbot.sim.naming import sensor_frame, sensor_rate
from simbot.sim.rates import Sampled
from simbot.sim.render import CameraSpec, Frame
from simbot.sim.render.contract import RenderStatus
from simbot.sim.sensor_params import Noise, SdfElement
from simbot.sim.system import SystemConfigError, SystemContext, UpdateInfo

CHANNELS = {"R8G8B8": 3, "RGB_INT8": 3, "L8": 1, "L_INT8": 1}
"""SDF image formats simbot renders, by the number of uint8 channels (rgb8, mono8)."""
DEFAULT_RATE_HZ = 30.0
MAX_SIDE = 8192


@dataclass(frozen=True)
class CameraParams:
    """A camera's SDF parameters (the table in the module docstring), checked."""

    horizontal_fov: float = 1.047
    width: int = 320
    height: int = 240
    format: str = "R8G8B8"
    near: float = 0.1
    far: float = 100.0
    noise_stddev: float = 0.0

    @staticmethod
    def from_sdf(sensor: Sensor, color: bool = True) -> CameraParams:
        camera = SdfElement.of(sensor).child("camera")
        if camera is None:
            raise SystemConfigError(f"sensor {sensor.name}: type {sensor.type!r} needs a <camera> element")
        image, clip = camera.child_or_empty("image"), camera.child_or_empty("clip")
        params = CameraParams(
            horizontal_fov=camera.number("horizontal_fov", 1.047),
            width=image.integer("width", 320),
            height=image.integer("height", 240),
            format=image.text("format", "R8G8B8") or "R8G8B8",
            near=clip.number("near", 0.1),
            far=clip.number("far", 100.0),
            noise_stddev=(camera.noise() or Noise()).applied.stddev,
        )
        for tag, value in (("width", params.width), ("height", params.height)):
            if not 1 <= value <= MAX_SIDE:
                raise image.error(tag, f"must be 1..{MAX_SIDE} pixels, got {value}")
        if not 0.0 < params.horizontal_fov < math.pi:
            raise camera.error("horizontal_fov", f"must be in (0, π) radians, got {params.horizontal_fov}")
        if not 0.0 < params.near < params.far:
            raise clip.error("near", f"and <far> need 0 < near < far, got near {params.near} far {params.far}")
        if color and params.format not in CHANNELS:
            raise image.error("format", f"{params.format!r} is not rendered; use one of {', '.join(CHANNELS)}")
        if params.noise_stddev < 0:
            raise camera.error("noise", f"stddev must be >= 0, got {params.noise_stddev}")
        return params


def camera_info_key(image_key: str) -> str:
    """Gazebo's camera_info key beside an image key (see the module docstring)."""
    parent, _, last = image_key.rpartition("/")
    return f"{parent}/camera_info" if parent else f"{last}/camera_info"


@dataclass(frozen=True)
class Output:
    """One published product of a frame: its publisher and how the frame becomes its message."""

    publisher: Publisher
    message: Callable[[Frame], Any]


class Camera(Sampled):
    """sensor_msgs/Image on `<topic>` and CameraInfo beside it, at the camera's rate."""

    depth = False
    """Whether the camera renders depth (a subclass that publishes depth sets it)."""
    kind = "image"
    """The last segment of Gazebo's default key (`world/<w>/model/<m>/link/<l>/sensor/<s>/image`)."""
    color = True

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        params = CameraParams.from_sdf(sensor, self.color)
        width, height = ctx.override("camera.size") or (params.width, params.height)
        self.spec = CameraSpec(
            sensor.name,
            width,
            height,
            params.horizontal_fov,
            params.near,
            params.far,
            channels=CHANNELS.get(params.format, 3) if self.color else 0,
            depth=self.depth,
            points=self.depth and self.color,
            noise_stddev=params.noise_stddev,
            seed=int(ctx.rng.integers(2**31)),
        )
        super().__init__(sensor.name, ctx.override("camera.rate") or sensor_rate(sensor, DEFAULT_RATE_HZ))
        self.where = (model, link.name, sensor.pose)
        self.frame_id = optical_frame(sensor_frame(sensor))
        topic = ctx.sensor_topic(self.kind)
        self.outputs = self.advertise(ctx.bus, topic)
        self._info = ctx.bus.publisher(self.info_key(topic), messages.CameraInfo)
        self.status = RenderStatus()
        """The world's rendering system shares its own when it takes the camera."""
        self.skipped = 0

    def advertise(self, bus: SimBus, topic: str) -> list[Output]:
        """The camera's products: here the colour image on the sensor's topic."""
        return [
            Output(bus.publisher(topic, messages.Image), lambda f: messages.image(f.stamp_ns, self.frame_id, f.rgb()))
        ]

    def info_key(self, topic: str) -> str:
        return camera_info_key(topic)

    def wanted(self) -> bool:
        return any(output.publisher.has_subscribers for output in self.outputs)

    def publish(self, frame: Frame) -> None:
        """Each subscribed product, then camera_info, all under the frame's stamp (the sim time it shows)."""
        for output in self.outputs:
            if output.publisher.has_subscribers:
                output.publisher.put(output.message(frame))
        self.publish_info(frame.stamp_ns)
        self.published(frame.stamp_ns)

    def publish_info(self, stamp_ns: int) -> None:
        if self._info.has_subscribers:
            spec = self.spec
            cx, cy = spec.principal_point
            self._info.put(
                messages.camera_info(stamp_ns, self.frame_id, spec.width, spec.height, spec.fx, spec.fx, cx, cy)
            )

    def report(self) -> dict[str, Any]:
        figures = super().report() | {"skipped": self.skipped, "size": [self.spec.width, self.spec.height]}
        if self.status.renderer is not None:
            figures["renderer"] = self.status.renderer
        if self.status.failure is not None:
            figures["error"] = self.status.failure
        return figures

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        self.skipped = 0
