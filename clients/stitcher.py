"""The camera stitcher: the robot's six images as one 360° panorama (SPEC §5).

The six images (`camera_front`, `camera_front_right`, `camera_back_right`, `camera_back`,
`camera_back_left`, `camera_front_left`) are grouped by stamp (StampSync, slop 0.1 s) and come
out as one image on `camera_360/image_raw`, with `camera_360/camera_info` of the same size and
stamp. The stitcher publishes nothing on tf. Two layouts (`--layout`):

- `strip`: the six images side by side in the order above, as the original ROS stitcher did;
  each tile is the camera's image untouched, so anything in two cameras' overlap shows twice.
  camera_info is the front camera's (frame `camera_front_optical_frame`, its K and D): tile 0 is
  exactly the front image, and tile i is camera i with the same K shifted by i·w columns, in its
  own optical frame (the six cameras share their intrinsics on the Tug).
- `cylindrical` (the default): every camera reprojected by its intrinsics (camera_info's K, and
  its plumb_bob D as cv2.projectPoints applies it: a lens's bent image comes out straight) and its
  optical frame's pose in `base_link` (tf_static) onto a vertical cylinder of radius `--radius`
  (default 3 m) about base_link's z axis, unrolled. Columns are azimuth (REP-103: about +z from
  +x), decreasing to the right, so the image reads like a person on base_link turning right:
  front in the middle, left (+y) left of it, right (−y) right of it, behind at both edges (the
  seam at ±π, where nobody looks). Rows are height on the cylinder, square pixels on its
  surface. Stamped in `base_link`; K = [fx 0 cx; 0 fy cy; 0 0 1] is that of a central
  cylindrical camera on base_link's z axis: a point (x, y, z) of base_link lies at
      u = cx − fx·atan2(y, x),   v = cy − fy·z / hypot(x, y),
  exactly for points on the cylinder (fx = fy = W/2π px per radian; cx = (W−1)/2, the column of
  azimuth 0; cy the row of base_link's z = 0). Points off the cylinder are drawn where the
  camera's ray through them meets it: a vertical edge at the radius seen by two neighbouring
  cameras lines up; nearer or farther ones are doubled or cut at a seam by the parallax of the
  two cameras (0.5 to 2 m apart). 3 m is the distance of what typically surrounds the Tug in an
  aisle (racks, pillars, another robot). Size: 3w × h for w × h cameras (1920 × 480 for 640 × 480:
  5.3 px per degree of azimuth, about what the cameras resolve at their centres, 4.8), centred
  on the cameras' mean height, ±38° of elevation; the top and bottom of the four seams next to
  the side cameras lie beyond the corners of the images and stay black.
  Where cameras overlap, each panorama pixel takes the camera that sees it nearest its optical
  axis (the sharpest, least stretched view); no blending, which would ghost what lies off the
  cylinder.

Why cylindrical by default: it is a real 360° image, one column per bearing from base_link,
with no object shown twice at tile borders, and K says how to get a bearing from a column; the
strip is for compatibility. Both stitch six 640 × 480 images well within a frame (see
benchmarks/bench_stitcher.py).

Input, pairing, partial sets:
- A set is one image per camera within 0.1 s; a set still missing a camera goes out once the
  other cameras' stamps are 0.2 s past it (the server renders the six at one tick, so sets are
  complete unless a camera is broken or silent). The panorama carries the newest stamp of the
  images stitched into it.
- A camera missing from a set (no image, or one that is refused) leaves its tile black in the
  strip; in the cylinder its sector is filled by its neighbours where they see it and is black
  where only it does. A set with no usable image gives no panorama.
- rgb8 and mono8 images are stitched (mono8 as grey); another encoding, a size that is not the
  camera_info's, or data shorter than height × step is skipped with a warning (at most one a
  second per camera). An image is only used once its camera_info has come, and in the cylinder
  once tf_static places its frame.

The stitch itself (`StripStitcher`, `CylinderStitcher`) takes pixel arrays, intrinsics and
poses and no bus, so the benchmark and the tests use it directly. The cylinder's remap tables
(fixed-point, cv2.convertMaps) are computed once per camera geometry and set of cameras present,
and again only when a camera's size, intrinsics or pose change. Zenoh callbacks only pair images
(StampSync) and queue; stitching and publishing happen in the client's loop.
"""

from __future__ import annotations

import functools
import logging
import math
import sys
import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import numpy as np
import numpy.typing as npt

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.frames import optical_frame
from simbot.bus.intrinsics import BadInput, Intrinsics
from simbot.bus.node import RateLimitedWarnings
from simbot.bus.tf_tree import Matrix

from .camera_model import pixels, undoable
from .common import ClockSubscriber, Mailbox, StampedSets, StaticTransforms, client_parser, run_client

logger = logging.getLogger("simbot.stitcher")

CAMERAS = (
    "camera_front",
    "camera_front_right",
    "camera_back_right",
    "camera_back",
    "camera_back_left",
    "camera_front_left",
)
"""The input topics, in the strip's order (SPEC §5)."""
IMAGE_TOPIC, INFO_TOPIC = "camera_360/image_raw", "camera_360/camera_info"
IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
BASE_FRAME = "base_link"
LAYOUTS = ("cylindrical", "strip")
DEFAULT_RADIUS_M = 3.0
SLOP_NS = 100_000_000
MAX_WAIT_NS = 200_000_000
WIDTH_PER_CAMERA = 3
"""Cylinder width in camera widths: 2π·3w px around ≈ the cameras' own px per radian at their centres."""
MAX_TABLES = 4
"""Remap tables kept per set of cameras present (a flaky camera must not rebuild them every set)."""
ENCODINGS = ("rgb8", "mono8")
"""What the panorama is made of (rgb8 out): colour as it comes, grey spread to three channels."""
POLL_S = 0.1
"""How often the loop looks at the stop flag while no set comes."""

Pixels = npt.NDArray[np.uint8]


@dataclass(frozen=True)
class CameraModel:
    """What the cylinder needs of a camera: its intrinsics and its optical frame's pose in base_link."""

    intrinsics: Intrinsics
    pose: tuple[float, ...]
    """The 4×4 matrix mapping optical-frame points into base_link, row by row (hashable, comparable)."""

    @classmethod
    def of(cls, intrinsics: Intrinsics, pose: Matrix) -> CameraModel:
        return cls(intrinsics, tuple(float(v) for v in np.asarray(pose).reshape(-1)))

    def matrix(self) -> Matrix:
        return np.array(self.pose, dtype=np.float64).reshape(4, 4)


@dataclass(frozen=True)
class PanoramaInfo:
    """The panorama's camera_info fields: its frame and K (see the module docstring for their meaning)."""

    frame_id: str
    fx: float
    fy: float
    cx: float
    cy: float
    d: tuple[float, ...] = (0.0,) * 5


class Stitcher(Protocol):
    """A layout: images by camera name (missing ones absent) → the panorama."""

    @property
    def cameras(self) -> Mapping[str, object]:
        """The cameras it was built for (it is built again when they change)."""

    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...

    @property
    def info(self) -> PanoramaInfo | None:
        """The panorama's camera_info fields; None when they are not known."""

    def stitch(self, images: Mapping[str, Pixels]) -> Pixels: ...


def image_pixels(msg: Any, size: tuple[int, int] | None = None) -> Pixels:
    """An rgb8 or mono8 sensor_msgs/Image as H×W×3 rgb; BadInput when it is neither, when its data
    are short of height × step, or when it is not `size` (its camera_info's width, height)."""
    if msg.encoding not in ENCODINGS:
        raise BadInput(f"encoding {msg.encoding!r} is not one of {', '.join(ENCODINGS)}")
    width, height = int(msg.width), int(msg.height)
    if size is not None and (width, height) != size:
        raise BadInput(f"image {width}×{height} but camera_info says {size[0]}×{size[1]}")
    try:
        pixels = messages.image_pixels(msg)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    if pixels.ndim == 2:
        return np.asarray(cv2.cvtColor(np.ascontiguousarray(pixels), cv2.COLOR_GRAY2RGB), dtype=np.uint8)
    return pixels


class Tiles:
    """The images side by side, one tile per camera of the largest camera's size: the strip itself,
    and the cylinder's remap source (one remap for all cameras instead of one per camera)."""

    def __init__(self, sizes: Sequence[tuple[int, int]]) -> None:
        if not sizes:
            raise ValueError("no camera to stitch")
        self.width = max(w for w, _ in sizes)
        self.height = max(h for _, h in sizes)
        self.buffer: Pixels = np.zeros((self.height, len(CAMERAS) * self.width, 3), dtype=np.uint8)

    def offset(self, name: str) -> int:
        """The first column of a camera's tile."""
        return CAMERAS.index(name) * self.width

    def fill(self, images: Mapping[str, Pixels]) -> Pixels:
        """Each image top-left in its tile, the rest black; the buffer (reused: copy before the next fill)."""
        for name in CAMERAS:
            tile = self.buffer[:, self.offset(name) : self.offset(name) + self.width]
            image = images.get(name)
            if image is None:
                tile[...] = 0
                continue
            height, width = image.shape[:2]
            tile[:height, :width] = image
            tile[height:] = 0
            tile[:height, width:] = 0
        return self.buffer


class StripStitcher:
    """The six images side by side in SPEC order; camera_info is the front camera's (tile 0)."""

    def __init__(self, cameras: Mapping[str, Intrinsics]) -> None:
        self.cameras = dict(cameras)
        self.tiles = Tiles([(c.width, c.height) for c in self.cameras.values()])
        self.width, self.height = self.tiles.buffer.shape[1], self.tiles.buffer.shape[0]
        front = self.cameras.get(CAMERAS[0])
        self.info = PanoramaInfo(front.frame_id, front.fx, front.fy, front.cx, front.cy, front.d) if front else None

    def stitch(self, images: Mapping[str, Pixels]) -> Pixels:
        return self.tiles.fill(images)


class CylinderStitcher:
    """Every camera reprojected onto a cylinder of `radius` about base_link's z axis, unrolled; the
    panorama is stamped in `frame`, that base_link's id (`tug_2/base_link` for a robot in namespace tug_2)."""

    def __init__(self, cameras: Mapping[str, CameraModel], radius: float, frame: str = BASE_FRAME) -> None:
        if not (radius > 0 and math.isfinite(radius)):
            raise ValueError(f"radius must be a positive number of metres, not {radius}")
        self.cameras = dict(cameras)
        self.radius = radius
        self.tiles = Tiles([(c.intrinsics.width, c.intrinsics.height) for c in self.cameras.values()])
        self.width, self.height = WIDTH_PER_CAMERA * self.tiles.width, self.tiles.height
        f = self.width / (2 * math.pi)
        centre_z = float(np.mean([c.matrix()[2, 3] for c in self.cameras.values()]))
        self.info = PanoramaInfo(frame, f, f, (self.width - 1) / 2, (self.height - 1) / 2 + f * centre_z / radius)
        self._tables: OrderedDict[frozenset[str], tuple[npt.NDArray[Any], npt.NDArray[Any]]] = OrderedDict()
        self._out: Pixels = np.zeros((self.height, self.width, 3), dtype=np.uint8)

    def stitch(self, images: Mapping[str, Pixels]) -> Pixels:
        """The panorama (a buffer reused by the next call) from the images present."""
        present = frozenset(name for name in images if name in self.cameras)
        map1, map2 = self.tables(present)
        source = self.tiles.fill(images)
        return np.asarray(
            cv2.remap(source, map1, map2, cv2.INTER_LINEAR, dst=self._out, borderMode=cv2.BORDER_CONSTANT),
            dtype=np.uint8,
        )

    def tables(self, present: frozenset[str]) -> tuple[npt.NDArray[Any], npt.NDArray[Any]]:
        """The fixed-point remap tables for this set of cameras, computed on its first use."""
        tables = self._tables.get(present)
        if tables is None:
            map_x, map_y = self.source_coordinates(present)
            tables = self._tables[present] = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
            if len(self._tables) > MAX_TABLES:
                self._tables.popitem(last=False)
        self._tables.move_to_end(present)
        return tables

    def surface(self) -> tuple[Matrix, Matrix, Matrix]:
        """x, y, z in base_link of every panorama pixel's point on the cylinder (H×W each)."""
        info, radius = self.info, self.radius
        azimuth = (info.cx - np.arange(self.width)) / info.fx
        height = (info.cy - np.arange(self.height)) * radius / info.fy
        x = np.broadcast_to(radius * np.cos(azimuth), (self.height, self.width))
        y = np.broadcast_to(radius * np.sin(azimuth), (self.height, self.width))
        z = np.broadcast_to(height[:, None], (self.height, self.width))
        return x, y, z

    def source_coordinates(self, present: frozenset[str]) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Where each panorama pixel comes from in the tiles: the camera seeing it nearest its optical
        axis, among those present; (−1, −1), outside the tiles (black), where none sees it."""
        x, y, z = self.surface()
        best = np.zeros((self.height, self.width))  # cosine of the off-axis angle; 0: no camera yet
        map_x = np.full((self.height, self.width), -1.0, dtype=np.float32)
        map_y = np.full((self.height, self.width), -1.0, dtype=np.float32)
        for name in CAMERAS:
            if name not in present:
                continue
            camera = self.cameras[name]
            k, pose = camera.intrinsics, camera.matrix()
            dx, dy, dz = x - pose[0, 3], y - pose[1, 3], z - pose[2, 3]
            r = pose[:3, :3]  # optical axes in base_link: the point in the optical frame is rᵀ·d
            ox = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
            oy = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            oz = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            ahead = oz > 1e-9
            depth = np.where(ahead, oz, 1.0)
            u, v = pixels(k, ox / depth, oy / depth)
            cosine = oz / np.sqrt(dx * dx + dy * dy + dz * dz)
            take = ahead & (u >= -0.5) & (u <= k.width - 0.5) & (v >= -0.5) & (v <= k.height - 0.5) & (cosine > best)
            best[take] = cosine[take]
            # clamped inside the tile, so that interpolation never reads a neighbouring tile
            map_x[take] = np.clip(u[take], 0, k.width - 1) + self.tiles.offset(name)
            map_y[take] = np.clip(v[take], 0, k.height - 1)
        return map_x, map_y


class StitcherNode:
    """The stitcher on the bus: images paired on Zenoh's threads, stitched and published in `spin_once`."""

    def __init__(self, node: Node, layout: str, radius: float) -> None:
        self.layout = layout
        self.radius = radius
        self.published = 0
        self.partial = 0
        self.skipped = 0
        self._warnings = RateLimitedWarnings()
        self._clock = ClockSubscriber(node)  # says when sim time goes back; the grouping starts afresh by itself
        self._tf = StaticTransforms(node, BASE_FRAME)
        self._intrinsics: dict[str, Intrinsics] = {}
        self._stitcher: Stitcher | None = None
        self._infos: Mailbox[tuple[str, Any]] = Mailbox(size=8 * len(CAMERAS))
        self._image_out = node.publisher(IMAGE_TOPIC, messages.Image)
        self._info_out = node.publisher(INFO_TOPIC, messages.CameraInfo)
        for name in CAMERAS:  # before the images: a camera's first image then finds its camera_info here
            node.subscribe(f"{name}/camera_info", CAMERA_INFO, functools.partial(self._info_of, name))
        self._images = StampedSets(node, CAMERAS, IMAGE, SLOP_NS, MAX_WAIT_NS, queue=2)

    def _info_of(self, name: str, info: Any) -> None:
        """Zenoh thread: a camera_info to the loop, tagged with its camera."""
        self._infos.put((name, info))

    @property
    def undecodable(self) -> int:
        """Input payloads that were not Images (dropped by the subscriptions)."""
        return self._images.undecodable

    def spin_once(self, timeout: float) -> None:
        """Stitch and publish the next set, if one comes within `timeout`, with the transforms and
        camera_infos that came before it."""
        ready = self._images.get(timeout)
        self._tf.refresh()
        while (item := self._infos.get(0.0)) is not None:
            name, info = item
            try:
                self._intrinsics[name] = undoable(info)
            except BadInput as exc:
                self._warnings.warn(f"{name}/camera_info", f"ignored: {exc}")
        if ready is not None:
            self._publish(ready)

    def _cylinder_cameras(self) -> dict[str, CameraModel]:
        """The cameras whose intrinsics and pose are known (a camera tf_static does not place is left out)."""
        cameras = {}
        for name, intrinsics in self._intrinsics.items():
            try:
                pose = self._tf.pose(intrinsics.frame_id)  # ValueError when tf_static holds a cycle
            except ValueError as exc:
                pose, reason = None, str(exc)
            else:
                target = self._tf.target_of(intrinsics.frame_id)
                reason = f"no transform from {intrinsics.frame_id!r} to {target!r} on tf_static (yet)"
            if pose is None:
                self._warnings.warn(name, f"left out of the panorama: {reason}")
                continue
            cameras[name] = CameraModel.of(intrinsics, pose)
        return cameras

    def stitcher(self) -> Stitcher | None:
        """The stitcher for the cameras known now, built again only when their geometry changed."""
        current = self._stitcher.cameras if self._stitcher is not None else None
        if self.layout == "cylindrical":
            models = self._cylinder_cameras()
            if models and models != current:
                frame = self._tf.target_of(next(iter(models.values())).intrinsics.frame_id)  # the cameras' robot's
                self._stitcher = CylinderStitcher(models, self.radius, frame)
        elif self._intrinsics and self._intrinsics != current:
            self._stitcher = StripStitcher(self._intrinsics)
        if self._stitcher is not None and self._stitcher.cameras is not current:
            used = ", ".join(name for name in CAMERAS if name in self._stitcher.cameras)
            logger.info("%s panorama %d×%d from %s", self.layout, self._stitcher.width, self._stitcher.height, used)
        return self._stitcher

    def _usable(self, name: str, image: Any, stitcher: Stitcher) -> Pixels | None:
        """The image's pixels, or None when it cannot be stitched (with a warning when the image is at fault)."""
        intrinsics = self._intrinsics.get(name)
        try:
            pixels = image_pixels(image, (intrinsics.width, intrinsics.height) if intrinsics else None)
        except BadInput as exc:
            self._warnings.warn(name, f"image skipped: {exc}")
            pixels = None
        if pixels is not None and name not in stitcher.cameras:
            # the first images may come before their camera_info; a camera tf_static does not place
            # was warned about; the "panorama from" line names the cameras stitched
            logger.debug("%s: image skipped: no camera_info or no pose for it yet", name)
            pixels = None
        self.skipped += pixels is None
        return pixels

    def _publish(self, ready: Mapping[str, Any]) -> None:
        """Stitch the usable images of a set and publish the panorama and its camera_info."""
        stitcher = self.stitcher()
        if stitcher is None:
            needs = "camera_info and tf_static" if self.layout == "cylindrical" else "camera_info"
            self._warnings.warn(IMAGE_TOPIC, f"waiting for {needs} before stitching")
            return
        images, stamps = {}, []
        for name, image in ready.items():
            pixels = self._usable(name, image, stitcher) if image is not None else None
            if pixels is not None:
                images[name] = pixels
                stamps.append(messages.stamp_ns(image.header))
        if not images:
            return
        stamp = max(stamps)
        info = stitcher.info
        panorama = stitcher.stitch(images)
        self._image_out.put(messages.image(stamp, info.frame_id if info else optical_frame(CAMERAS[0]), panorama))
        if info is not None:
            size = (stitcher.width, stitcher.height)
            self._info_out.put(
                messages.camera_info(stamp, info.frame_id, *size, info.fx, info.fy, info.cx, info.cy, info.d)
            )
        else:
            self._warnings.warn(INFO_TOPIC, "not published: no camera_info from camera_front yet")
        self.published += 1
        self.partial += len(images) < len(CAMERAS)

    def summary(self) -> str:
        return (
            f"published {self.published} panoramas ({self.partial} with a camera missing); "
            f"skipped {self.skipped} images, dropped {self.undecodable} undecodable payloads; "
            f"{self._images.overwritten} sets came faster than they could be stitched and were dropped; "
            f"sim time went back {self._clock.watch.jumps} times"
        )


def run(node: Node, stop: threading.Event, layout: str, radius: float) -> int:
    """Stitches the six cameras in `layout` (one of LAYOUTS; cylindrical at `radius` m) until `stop`."""
    stitcher = StitcherNode(node, layout, radius)
    where = f" on a cylinder of radius {radius:g} m about {BASE_FRAME}" if layout == "cylindrical" else ""
    logger.info("stitching %s into a %s panorama%s on %s", ", ".join(CAMERAS), layout, where, IMAGE_TOPIC)
    while not stop.is_set():
        stitcher.spin_once(POLL_S)
    logger.info("%s", stitcher.summary())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot stitcher`: the six camera images → camera_360/image_raw and camera_360/camera_info."""
    parser = client_parser("simbot stitcher", f"Stitch the six camera images into one 360° panorama on {IMAGE_TOPIC}.")
    parser.add_argument(
        "--layout",
        choices=LAYOUTS,
        default=LAYOUTS[0],
        help="cylindrical (default): reprojected by the cameras' poses onto a cylinder; strip: side by side",
    )
    parser.add_argument(
        "--radius",
        type=number(float),
        default=DEFAULT_RADIUS_M,
        metavar="METRES",
        help=f"cylindrical: radius of the cylinder about {BASE_FRAME} where neighbouring cameras line up"
        f" (default {DEFAULT_RADIUS_M:g})",
    )
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, args.layout, args.radius))


if __name__ == "__main__":
    sys.exit(main())
