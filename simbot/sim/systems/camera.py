"""Camera (SDF `camera`): images rendered by the rendering system, stamped with the sim time they show.

The world's one `Rendering` system (simbot/sim/systems/camera_rendering.py) finds the camera by its
`RenderedSensor` contract (simbot/sim/kit/rendered_sensor.py), schedules it and renders it in worker
processes. This module says what a camera renders
and how a frame becomes messages; `depth_camera` and `rgbd_camera` are the same camera with
other products. A camera's products are data (`Product`: the key under its topic, the output it
shows, how that becomes a message): a camera of a new kind declares its products, and its
outputs' kinds (simbot/sim/render/kinds.py) say how they are rendered.

Images are stamped in the camera's optical frame (z forward, x right, y down; tf_static places
it), as ROS expects of camera data. Its image key is `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/image` (`.../depth_image` for a depth camera). Every
frame goes out with its `camera_info` under the same stamp (image_transport's CameraSubscriber,
RViz and exact-time synchronisers pair them by stamp); while only camera_info is subscribed, it
goes out at the camera's rate without rendering. A frame's messages are put on the bus by the
render worker that drew it (`publication`, simbot/sim/render/publishing.py): the physics process
never carries its pixels; a camera whose messages need what only the server holds (bounding boxes:
the world's geometry) says `published_by_worker = False` and publishes them here. camera_info holds the camera's true intrinsics:
fx = fy = (w/2)/tan(hfov/2), principal point at the image centre ((w−1)/2, (h−1)/2 in ROS's
pixel-centre coordinates, where the symmetric frustum puts it), distortion_model `plumb_bob` with
D = [k1, k2, p1, p2, k3] of `<distortion>` (all zero without one). A lens that bends the image
puts the principal point at its `<center>` (simbot/sim/render/lens.py says how the image is bent,
so that cv2.undistortPoints with this K and D straightens it). Its key is the image key's sibling, as Gazebo names it: the last
segment replaced by `camera_info` (`a/b/image` → `a/b/camera_info`), or `<key>/camera_info` for a
key of one segment (`camera_front` → `camera_front/camera_info`).

SDF parameters (under `<camera>`; `CameraParams`):

| element | default | meaning |
| --- | --- | --- |
| `<horizontal_fov>` | 1.047 | radians, in (0, π) |
| `<image><width>`, `<height>` | 320, 240 | pixels, 1..8192 (`--camera-size` overrides) |
| `<image><format>` | R8G8B8 | R8G8B8 / RGB_INT8 (rgb8) or L8 / L_INT8 (mono8); depth cameras ignore it |
| `<clip><near>`, `<far>` | 0.1, 100 | metres, 0 < near < far |
| `<noise>` (`type`, `stddev`) | none | gaussian pixel noise, fraction of full scale, after the lens |
| `<distortion>` `<k1>` `<k2>` `<k3>` `<p1>` `<p2>` | 0 | plumb_bob lens distortion of colour, depth and points |
| `<distortion><center>` | 0.5 0.5 | distortion centre, normalised image coordinates; the principal point |
| `<update_rate>` (of the `<sensor>`) | 30 | frames per second (`--camera-rate` overrides) |
| `<save enabled="true"><path>` | off | every frame also written to the folder in simbot's dataset layout (simbot/sim/kit/camera_save.py) |

Command-line parameters (`RunOptions.overrides`): `camera.size` ((width, height)), `camera.rate` (Hz).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from simbot.bus import Publisher, messages
from simbot.bus.frames import optical_frame, with_frame_prefix
from simbot.description.model import Sensor
from simbot.description.naming import sensor_frame, sensor_rate
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.camera_save import frame_saver
from simbot.sim.kit.rates import Sampled
from simbot.sim.kit.rendered_sensor import RenderStatus
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.sim.render import CameraSpec, Frame
from simbot.sim.render.lens import Distortion
from simbot.sim.render.publishing import Publication, Route
from simbot.sim.render.wide_lens import WideLens

COLOR_OUTPUTS = {"R8G8B8": "color", "RGB_INT8": "color", "L8": "mono", "L_INT8": "mono"}
"""SDF image formats simbot renders, by the output that renders them (rgb8, mono8)."""
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
    distortion: Distortion = Distortion()

    @staticmethod
    def from_sdf(sensor: Sensor, color: bool = True, widest: float = math.pi) -> CameraParams:
        """`widest`: the field of view it may not reach (a wide-angle lens's is 2π and more)."""
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
            distortion=_distortion(camera.child_or_empty("distortion")),
        )
        for tag, value in (("width", params.width), ("height", params.height)):
            if not 1 <= value <= MAX_SIDE:
                raise image.error(tag, f"must be 1..{MAX_SIDE} pixels, got {value}")
        if not 0.0 < params.horizontal_fov < widest:
            limit = "π" if widest == math.pi else f"{widest:.4f}"
            raise camera.error("horizontal_fov", f"must be in (0, {limit}) radians, got {params.horizontal_fov}")
        if not 0.0 < params.near < params.far:
            raise clip.error("near", f"and <far> need 0 < near < far, got near {params.near} far {params.far}")
        if color and params.format not in COLOR_OUTPUTS:
            raise image.error("format", f"{params.format!r} is not rendered; use one of {', '.join(COLOR_OUTPUTS)}")
        if params.noise_stddev < 0:
            raise camera.error("noise", f"stddev must be >= 0, got {params.noise_stddev}")
        return params


def _distortion(lens: SdfElement) -> Distortion:
    """SDF `<distortion>`: every element optional, zero (the centre 0.5 0.5) when absent."""
    k1, k2, k3, p1, p2 = (lens.number(tag, 0.0) for tag in ("k1", "k2", "k3", "p1", "p2"))
    cx, cy = lens.numbers("center", (0.5, 0.5))
    return Distortion(k1, k2, k3, p1, p2, (cx, cy))


def _without_noise(sensor: Sensor) -> Sensor:
    """The sensor but for its camera's `<noise>`."""
    params = tuple(
        replace(p, children=tuple(c for c in p.children if c.tag != "noise")) if p.tag == "camera" else p
        for p in sensor.params
    )
    return replace(sensor, params=params)


def camera_info_key(image_key: str) -> str:
    """Gazebo's camera_info key beside an image key (see the module docstring)."""
    parent, _, last = image_key.rpartition("/")
    return f"{parent}/camera_info" if parent else f"{last}/camera_info"


@dataclass(frozen=True)
class Message:
    """How an output's array becomes a message: its type, and its builder (stamp ns, frame id, array)."""

    type: type[Any]
    build: Callable[[int, str, Any], Any]


IMAGES = {
    "rgb8": Message(messages.Image, messages.image),
    "mono8": Message(messages.Image, messages.image),
    "32FC1": Message(messages.Image, messages.depth_image),
}
"""sensor_msgs/Image builders by the encoding an output kind gives (`OutputKind.encoding`)."""
POINT_CLOUD = Message(messages.PointCloud2, messages.point_cloud)


@dataclass(frozen=True)
class Product:
    """One published product of a camera, as data."""

    key: str
    """Under the camera's topic (`<topic>/<key>`); "" for the topic itself."""
    output: str
    """The output it shows, by kind name; `color` is rendered as the SDF image format says (`COLOR_OUTPUTS`)."""
    message: Message | None = None
    """None: a sensor_msgs/Image in the encoding of the output's kind (`IMAGES`)."""


@dataclass(frozen=True)
class _Published:
    publisher: Publisher
    output: str
    build: Callable[[int, str, Any], Any]


class Camera(Sampled):
    """sensor_msgs/Image on `<topic>` and CameraInfo beside it, at the camera's rate."""

    products: tuple[Product, ...] = (Product("", "color"),)
    kind = "image"
    """The last segment of Gazebo's default key (`world/<w>/model/<m>/link/<l>/sensor/<s>/image`)."""
    in_optical_frame = True
    """Its messages are stamped in the optical frame, which the robot's tf_static adds for it."""
    formats = COLOR_OUTPUTS
    """The output that renders a `color` product, by SDF image format."""
    widest = math.pi
    """The horizontal field of view it cannot reach."""
    published_by_worker = True
    """Its frames' messages are put on the bus by the render worker that drew them (`publication`)."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        color = any(product.output == "color" for product in self.products)
        params = CameraParams.from_sdf(sensor, color, self.widest)
        width, height = ctx.override("camera.size") or (params.width, params.height)
        wide = self.wide_lens(sensor)
        outputs = [self.formats[params.format] if p.output == "color" else p.output for p in self.products]
        self.spec = CameraSpec(
            sensor.name,
            width,
            height,
            params.horizontal_fov,
            params.near,
            params.far,
            outputs=tuple(dict.fromkeys(outputs)),
            noise_stddev=params.noise_stddev,
            seed=int(ctx.rng.integers(2**31)),
            distortion=params.distortion if wide is None else Distortion(),  # the wide lens bends it alone
            wide=wide,
        )
        super().__init__(sensor.name, ctx.override("camera.rate") or sensor_rate(sensor, DEFAULT_RATE_HZ))
        self.sensor = sensor
        self.where = (model, link.name, sensor.pose)
        self.frame_id = optical_frame(sensor_frame(sensor))
        topic = ctx.sensor_topic(self.kind)
        self.outputs = [
            self._advertise(ctx.bus, topic, product, output)
            for product, output in zip(self.products, outputs, strict=True)
        ]
        self._info = ctx.bus.publisher(self.info_key(topic), messages.CameraInfo)
        by_worker = self.published_by_worker and ctx.bus.node.hosts_helpers
        self.publication = self._publication(ctx.bus) if by_worker else None
        """What its render worker publishes of each frame; None: the server publishes them (`send`),
        as where no worker can reach the bus."""
        self.status = RenderStatus()
        """The world's rendering system shares its own when it takes the camera."""
        self.skipped = 0
        self.saver = frame_saver(sensor, topic, self.spec)
        """Gazebo's `<save>`: every frame also written to a dataset folder (simbot/sim/kit/camera_save.py)."""

    def retune(self, sensor: Sensor) -> bool:
        """Its `<sensor>` as a seeded reset draws it, in place (simbot.sim.loop.world_edit): only the
        camera's `<noise>` may differ; the spec takes its deviation, and the render pool the spec.
        False, and nothing changed, for any other difference."""
        if _without_noise(sensor) != _without_noise(self.sensor):
            return False
        color = any(product.output == "color" for product in self.products)
        try:
            noise = CameraParams.from_sdf(sensor, color, self.widest).noise_stddev
        except SystemConfigError:
            return False
        self.spec, self.sensor = replace(self.spec, noise_stddev=noise), sensor
        return True

    def wide_lens(self, sensor: Sensor) -> WideLens | None:
        """The wide-angle lens it sees through (`wide_angle_camera.py`); None: a pinhole camera."""
        return None

    def _advertise(self, bus: SimBus, topic: str, product: Product, output: str) -> _Published:
        kind = next(kind for kind in self.spec.kinds if kind.name == output)
        message = product.message or IMAGES.get(kind.encoding or "")
        if message is None:
            raise SystemConfigError(
                f"camera {self.spec.name}: output {output!r} is no image; its product needs a message"
            )
        key = f"{topic}/{product.key}" if product.key else topic
        return _Published(bus.publisher(key, message.type), output, message.build)

    def _publication(self, bus: SimBus) -> Publication:
        """Its products and camera_info as a render worker puts them, frame ids in the model's namespace."""
        routes = tuple(Route(o.publisher.key, o.publisher.typename or "", o.output, o.build) for o in self.outputs)
        info = with_frame_prefix(self.camera_info(0), self._info.frame_prefix)
        return Publication(bus.frame(self.frame_id), routes, self._info.key, info)

    def info_key(self, topic: str) -> str:
        return camera_info_key(topic)

    def wanted(self) -> bool:
        return self.saver is not None or any(output.publisher.has_subscribers for output in self.outputs)

    def audience(self) -> frozenset[str]:
        """The keys of its publication that someone subscribes to now, by the server's own publishers."""
        watched = [self._info, *(output.publisher for output in self.outputs)]
        return frozenset(publisher.key for publisher in watched if publisher.has_subscribers)

    def publish(self, frame: Frame) -> None:
        """A frame done: its products, then camera_info, all under the frame's stamp (the sim time it
        shows), unless its worker published them; counted; and to disk where `<save>` says."""
        if self.publication is None:
            self.send(frame)
            self.publish_info(frame.stamp_ns)
        self.published(frame.stamp_ns)
        if self.saver is not None:
            self.saver.save(frame)

    def send(self, frame: Frame) -> None:
        """Each subscribed product (a camera of another kind sends its own)."""
        for output in self.outputs:
            if output.publisher.has_subscribers:
                output.publisher.put(output.build(frame.stamp_ns, self.frame_id, frame[output.output]))

    def publish_info(self, stamp_ns: int) -> None:
        if self._info.has_subscribers:
            self._info.put(self.camera_info(stamp_ns))

    def camera_info(self, stamp_ns: int) -> Any:
        """sensor_msgs/CameraInfo of its true intrinsics (the module docstring)."""
        spec = self.spec
        cx, cy = spec.principal_point
        return messages.camera_info(
            stamp_ns, self.frame_id, spec.width, spec.height, spec.fx, spec.fx, cx, cy, spec.distortion.d
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

    def close(self) -> None:
        if self.saver is not None:
            self.saver.close()
