"""`simbot dataset --out DIR [--cameras KEY…] [--every N] [--count N] [--randomise SEEDS]`: synchronised
camera frames as a training set, in the layout of simbot/dataset_format.py (PNGs, COCO
annotations.json, manifest.json).

`--randomise SEEDS` (a count N: seeds 0..N-1; or FIRST:END) asks the world, for each seed in turn,
for the world that seed draws from its variation profile (world control's `reset` with the seed,
simbot.variation) and writes `--count` sets of each, their files and sets marked with the seed. The
server runs the world (real time or fast); a lockstep world is the caller's to step.

Each KEY names a camera by its key (relative to `--robot-namespace`), and is one of:
- an image key (sensor_msgs/Image): rgb8, bgr8 or mono8 → `rgb` PNG; 32FC1 depth → `depth` PNG (mm);
- a segmentation camera's topic (`KEY/labels_map`, rgb8, each pixel [count & 0xFF, count >> 8,
  label] in instance or panoptic mode; [label, label, label] in semantic mode, where a label's
  pixels are one instance) → `labels` and `instances` PNGs and COCO instance masks;
- a bounding-box camera's key (vision_msgs/Detection2DArray, class_id = the label) → COCO boxes.
Without `--cameras`, every image key of the robot that has a CameraInfo beside it, every
segmentation camera and every bounding-box camera.

A set is one frame of every chosen camera under one stamp (a world's cameras render as a set and
share it); its camera_info (the nearest CameraInfo key up the camera's key: `a/b/camera_info` for
`a/b/image` or `a/b`) gives the intrinsics. Sets that never complete (a camera fell silent for a
second of sim time) are dropped and counted. `--every N` keeps the first set and every Nth after.

The pose of a frame is the camera's optical frame in the world: the robot's ground truth
(`/model/<robot>/pose`, linear between the two samples around the frame's stamp) composed with
the frame's place in the robot (`tf_static`, from its root link, which is taken to lie at the
model's origin as on simbot's robots). A set waits for the pose sample after its stamp; with no
ground truth at all (a static model, no tf_static) its poses are left null after `POSE_WAIT_S`.
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from simbot.arguments import number
from simbot.bus import Node, messages
from simbot.bus.frames import OPTICAL_SUFFIX
from simbot.bus.intrinsics import BadInput, Intrinsics
from simbot.bus.sync import StampSync
from simbot.bus.tf_tree import Matrix
from simbot.dataset_format import OPTICAL_IN_BODY, Box, DatasetWriter, Shot
from simbot.transform import Transform, matmul, norm

from .common import (
    ClientError,
    Mailbox,
    StaticTransforms,
    StatusLine,
    client_parser,
    followed_model,
    run_client,
)
from .topics import Topic, live_topics, world_names

logger = logging.getLogger(__name__)

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
DETECTIONS = "vision_msgs/msg/Detection2DArray"
POSE = "geometry_msgs/msg/PoseStamped"
LABELS_MAP = "labels_map"
MAX_WAIT_NS = 1_000_000_000
"""Sim time a set waits for its last frame before it is dropped as incomplete."""
POSE_WAIT_S = 3.0
"""Wall seconds a set waits for ground truth that never came, before its poses are left null."""
GRAPH_POLL_S = 0.5
QUEUE = 64
RESET_S = 60.0
"""Seconds a seeded reset may take beyond `--timeout`: where the variant cannot be applied in place,
the server loads the whole world anew (docs/variation.md)."""

Kind = Literal["image", "segmentation", "boxes"]


@dataclass(frozen=True)
class Source:
    """A chosen camera: its name (as given), the key it is read from and what it carries."""

    camera: str
    topic: str
    typename: str
    kind: Kind
    info: str | None


def scoped(name: str, robot_namespace: str) -> str:
    """A topic name relative to the bus namespace, as the graph lists it."""
    name = name.strip()
    if name.startswith("/") or not robot_namespace:
        return name.strip("/")
    return f"{robot_namespace.strip('/')}/{name.strip('/')}"


def info_of(full: str, topics: dict[str, Topic]) -> str | None:
    """The nearest CameraInfo key up a camera's key (`a/b/camera_info` for `a/b/image` or `a/b`)."""
    parts = full.split("/")
    for end in range(len(parts), 0, -1):
        candidate = "/".join([*parts[:end], "camera_info"])
        if candidate in topics and topics[candidate].typename == CAMERA_INFO:
            return candidate
    return None


def resolve(camera: str, full: str, topics: dict[str, Topic]) -> Source | None:
    """What `camera` (`full` in the bus namespace) is on the graph, or None when nothing publishes it."""
    seg = f"{full}/{LABELS_MAP}"
    if seg in topics and "pub" in topics[seg].kinds:
        return Source(camera, seg, IMAGE, "segmentation", info_of(full, topics))
    topic = topics.get(full)
    if topic is None or "pub" not in topic.kinds:
        return None
    if topic.typename == IMAGE:
        return Source(camera, full, IMAGE, "image", info_of(full, topics))
    if topic.typename == DETECTIONS:
        return Source(camera, full, DETECTIONS, "boxes", info_of(full, topics))
    return None


def every_camera(topics: dict[str, Topic], robot_namespace: str) -> list[Source]:
    """The default choice: the robot's images with a CameraInfo, segmentation and bounding-box cameras."""
    prefix = f"{robot_namespace.strip('/')}/" if robot_namespace.strip("/") else ""
    found = []
    for name, topic in sorted(topics.items()):
        if not name.startswith(prefix) or "pub" not in topic.kinds or name.endswith("/colored_map"):
            continue
        camera = name[len(prefix) :]
        if name.endswith(f"/{LABELS_MAP}"):
            found.append(resolve(camera.rpartition("/")[0], name.rpartition("/")[0], topics))
        elif topic.typename == DETECTIONS or (topic.typename == IMAGE and info_of(name, topics)):
            found.append(resolve(camera, name, topics))
    return [source for source in found if source is not None]


def find_sources(node: Node, names: Sequence[str], timeout: float, stop: threading.Event) -> list[Source]:
    """The chosen cameras as the graph shows them, waiting up to `timeout` s for all to appear."""
    deadline = time.monotonic() + timeout
    names = list(dict.fromkeys(names))
    while True:
        topics = live_topics(node)
        if names:
            sources = {n: resolve(n, scoped(n, node.robot_namespace), topics) for n in names}
            missing = [n for n, s in sources.items() if s is None]
            if not missing:
                return [s for s in sources.values() if s is not None]
        else:
            found = every_camera(topics, node.robot_namespace)
            if found:
                return found
        if time.monotonic() >= deadline or stop.is_set():
            break
        time.sleep(GRAPH_POLL_S)
    cameras = ", ".join(s.camera for s in every_camera(topics, node.robot_namespace)) or "none"
    if names:
        raise ClientError(
            f"--cameras: no camera {', '.join(missing)} on the bus within {timeout:g} s (cameras: {cameras})"
        )
    raise ClientError(f"no camera on the bus within {timeout:g} s: is the server running, with the same namespace?")


class PoseTrack:
    """The robot's ground truth over time: samples of `/model/<robot>/pose`, read at any stamp."""

    def __init__(self, node: Node, model: str) -> None:
        self.key = f"/model/{model}/pose"
        self._inbox: Mailbox[Any] = Mailbox(size=QUEUE)
        self._samples: deque[tuple[int, Transform]] = deque(maxlen=QUEUE)
        node.subscribe(self.key, POSE, self._inbox.put)

    def refresh(self) -> None:
        while (msg := self._inbox.get(0.0)) is not None:
            p, o = msg.pose.position, msg.pose.orientation
            stamp = messages.stamp_ns(msg.header)
            if self._samples and stamp < self._samples[-1][0]:
                self._samples.clear()  # sim time went back: another run
            self._samples.append((stamp, Transform.of((p.x, p.y, p.z), (o.x, o.y, o.z, o.w))))

    def forget(self) -> None:
        """Sim time starts again (a reset): the samples so far are another run's."""
        self._samples.clear()
        while self._inbox.get(0.0) is not None:
            pass

    def reached(self, stamp_ns: int) -> bool:
        """Whether a sample at or after `stamp_ns` has come (so the pose there is known)."""
        return bool(self._samples) and self._samples[-1][0] >= stamp_ns

    def at(self, stamp_ns: int) -> Matrix | None:
        """The model's pose at `stamp_ns`: linear between the samples around it, else the nearest."""
        if not self._samples:
            return None
        before = [s for s in self._samples if s[0] <= stamp_ns]
        after = [s for s in self._samples if s[0] >= stamp_ns]
        if not before or not after:
            return (before or after)[-1 if before else 0][1].matrix()
        (t0, a), (t1, b) = before[-1], after[0]
        return blend(a, b, 0.0 if t1 == t0 else (stamp_ns - t0) / (t1 - t0))


def blend(a: Transform, b: Transform, f: float) -> Matrix:
    """The pose a fraction `f` of the way from `a` to `b` (position linear, orientation normalised lerp)."""
    qa, qb = np.asarray(a.orientation), np.asarray(b.orientation)
    if float(matmul(qa, qb)) < 0:
        qb = -qb
    q = (1 - f) * qa + f * qb
    p = (1 - f) * np.asarray(a.position) + f * np.asarray(b.position)
    return Transform.of(p.tolist(), (q / norm(q)).tolist()).matrix()


def intrinsics_of(info: Any) -> Intrinsics | None:
    """What the camera_info states; None (the shot goes without) where it describes no camera."""
    try:
        return Intrinsics.from_info(info)
    except BadInput as exc:
        logger.warning("camera_info of %s left out of the shot: %s", info.header.frame_id, exc)
        return None


def fill(shot: Shot, source: Source, msg: Any) -> None:
    """The shot's pictures from its camera's message."""
    if source.kind == "boxes":
        shot.boxes = [box_of(d) for d in msg.detections]
    elif source.kind == "segmentation":
        shot.instances, shot.labels = split_labels_map(messages.image_pixels(msg))
    elif msg.encoding == "32FC1":
        shot.depth = messages.depth_pixels(msg)
    else:
        pixels = messages.image_pixels(msg)
        shot.color = (
            pixels[..., 2::-1] if msg.encoding in ("bgr8", "bgra8") else pixels[..., :3] if pixels.ndim == 3 else pixels
        )


def split_labels_map(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(instances, labels) of a labels_map: [count & 0xFF, count >> 8, label] per pixel; a semantic
    map ([label, label, label] everywhere) makes each label one instance."""
    low, high, label = (pixels[..., i] for i in range(3))
    if np.array_equal(low, label) and np.array_equal(high, label):
        return label.astype(np.uint16), label.copy()
    return (low.astype(np.uint16) | (high.astype(np.uint16) << 8)), label.copy()


def box_of(detection: Any) -> Box:
    """A Detection2D as COCO's box: Gazebo's (and the server's) size is max − min of the first and
    last pixel's indices, centred between them, so the box COCO measures (from the first pixel's
    edge, over whole pixels) starts at centre − size/2 and is one pixel wider and taller."""
    box = detection.bbox
    width, height = float(box.size_x), float(box.size_y)
    label = int(detection.results[0].hypothesis.class_id) if detection.results else 0
    x, y = float(box.center.position.x) - width / 2, float(box.center.position.y) - height / 2
    return Box(label, x, y, width + 1, height + 1)


@dataclass(frozen=True)
class Dataset:
    """What `simbot dataset` writes: where, of which cameras (none named: every camera of the
    robot), which sets and how many, and the worlds to draw."""

    out: Path
    cameras: Sequence[str] = ()
    every: int = 1  # keep every Nth set
    count: int | None = None  # sets to write (of each world when randomised); None: until stopped
    robot: str | None = None  # the model carrying the cameras; None: the followed robot
    timeout_s: float = 10.0  # how long to wait for the cameras
    randomise: range | None = None  # the seeds of the worlds to draw, `count` sets of each


class Collector:
    """The loop: complete sets from the sync, their poses, the kept ones written."""

    def __init__(self, node: Node, sources: list[Source], writer: DatasetWriter, dataset: Dataset) -> None:
        self.sources, self.writer, self.every, self.count = sources, writer, dataset.every, dataset.count
        infos = sorted({s.info for s in sources if s.info is not None})
        self.sync: StampSync[Any] = StampSync([s.camera for s in sources] + infos, 0, MAX_WAIT_NS)
        self.sets: Mailbox[dict[str, Any]] = Mailbox(size=QUEUE)
        for source in sources:
            node.subscribe("/" + source.topic, source.typename, functools.partial(self._receive, source.camera))
        for info in infos:
            node.subscribe("/" + info, CAMERA_INFO, functools.partial(self._receive, info))
        self.poses = PoseTrack(node, dataset.robot or followed_model(node.robot_namespace))
        self.tf = StaticTransforms(node, "base_link")
        self.pending: deque[tuple[float, dict[str, Any]]] = deque()
        self.seen = self.written = self.incomplete = self.unreadable = 0
        self.world_seed: int | None = None
        self._warned = False

    def restart(self, seed: int) -> None:
        """The world was drawn anew from `seed`: sim time starts again, and what came before belongs
        to the last one. Every frame of the last world came before the reset's reply (the server
        routes its render workers' frames, and a lockstep step ends only once they are routed), so
        what is queued now is dropped whole."""
        self.sync = StampSync(self.sync.streams, 0, MAX_WAIT_NS)
        while self.sets.get(0.0) is not None:
            pass
        self.pending.clear()
        self.poses.forget()
        self.world_seed = seed

    def _receive(self, stream: str, msg: Any) -> None:
        for ready in self.sync.add(stream, messages.stamp_ns(msg.header), msg):
            self.sets.put(ready)

    def take(self, timeout: float) -> None:
        """Queue the sets that came (every Nth complete one), then write those whose poses are known."""
        got = self.sets.get(timeout)
        while got is not None:
            if any(msg is None for msg in got.values()):
                self.incomplete += 1
            else:
                if self.seen % self.every == 0:
                    self.pending.append((time.monotonic(), got))
                self.seen += 1
            got = self.sets.get(0.0)
        self.poses.refresh()
        self.tf.refresh()
        while self.pending and not self.done:
            waited, ready = self.pending[0]
            if not self.poses.reached(_stamp(ready)) and time.monotonic() - waited < POSE_WAIT_S:
                return
            self.pending.popleft()
            self.write(ready)

    def write(self, ready: dict[str, Any]) -> None:
        """One set into the dataset; a set whose messages cannot be read is dropped with a warning."""
        try:
            shots = self.shots(ready)
        except (ValueError, IndexError) as exc:
            self.unreadable += 1
            logger.warning("dropped the set at %d ns: %s", _stamp(ready), exc)
            return
        try:
            self.writer.write(shots)
        except OSError as exc:
            raise ClientError(f"--out {self.writer.root}: cannot write there: {exc}") from None
        self.written += 1

    def shots(self, ready: dict[str, Any]) -> list[Shot]:
        stamp = _stamp(ready)
        shots = []
        for source in self.sources:
            msg = ready[source.camera]
            info = ready.get(source.info) if source.info else None
            shot = Shot(source.camera, stamp, None if info is None else intrinsics_of(info), world_seed=self.world_seed)
            shot.pose = self.pose(msg.header.frame_id, stamp)
            fill(shot, source, msg)
            shots.append(shot)
        return shots

    def pose(self, frame: str, stamp: int) -> Matrix | None:
        """The optical frame's pose in the world at `stamp`, or None (said once) without ground truth."""
        model = self.poses.at(stamp)
        placed = self.placed(frame.lstrip("/"))
        if model is not None and placed is not None:
            return matmul(model, placed)
        if not self._warned:
            self._warned = True
            what = f"no {self.poses.key}" if model is None else f"no {frame} in tf_static"
            logger.warning("poses left null: %s (is --robot the model that carries the cameras?)", what)
        return None

    def placed(self, frame: str) -> Matrix | None:
        """An optical frame in its robot's root link: from tf_static, else (the server names only a
        `camera`'s optical frame there) its body frame turned as optical frames are."""
        rooted = self.tf.rooted(frame)
        if rooted is None and frame.endswith(OPTICAL_SUFFIX):
            body = self.tf.rooted(frame.removesuffix(OPTICAL_SUFFIX))
            return None if body is None else matmul(body[1], OPTICAL_IN_BODY)
        return None if rooted is None else rooted[1]

    def flush(self) -> None:
        """Write what still waits for its pose (the nearest sample serves), then the JSON files."""
        try:
            while self.pending and not self.done:
                self.write(self.pending.popleft()[1])
        finally:
            try:
                self.writer.close()
            except OSError as exc:
                logger.error("--out %s: the manifest was not written: %s", self.writer.root, exc)

    @property
    def done(self) -> bool:
        return self.count is not None and self.written >= self.count

    def progress(self) -> str:
        dropped = (
            f"{self.incomplete} incomplete, {self.unreadable} unreadable, {self.sets.overwritten} not taken in time"
        )
        return f"{self.written} sets written of {self.seen} seen; dropped: {dropped}"


def _stamp(ready: dict[str, Any]) -> int:
    return next(messages.stamp_ns(msg.header) for msg in ready.values() if msg is not None)


def run(node: Node, stop: threading.Event, dataset: Dataset) -> int:
    """Writes `dataset` until its count or `stop`; the exit code."""
    try:
        writer = DatasetWriter(dataset.out)
    except OSError as exc:
        raise ClientError(f"--out {dataset.out}: cannot write there: {exc.strerror or exc}") from None
    sources = find_sources(node, dataset.cameras, dataset.timeout_s, stop)
    logger.info("cameras: %s", ", ".join(f"{s.camera} ({s.kind})" for s in sources))
    collector = Collector(node, sources, writer, dataset)
    status = StatusLine()
    try:
        if dataset.randomise is None:
            _collect(collector, status, stop)
        world = _world_control(node) if dataset.randomise else ""
        for index, seed in enumerate(dataset.randomise or ()):
            assert dataset.count is not None  # main refuses --randomise without --count
            _reset(node, world, seed, dataset.timeout_s)
            collector.restart(seed)
            collector.count = dataset.count * (index + 1)
            _collect(collector, status, stop)
    finally:
        collector.flush()
    print(f"wrote {writer.root}: {collector.progress()}", file=sys.stderr)
    return 0


def _collect(collector: Collector, status: StatusLine, stop: threading.Event) -> None:
    while not stop.is_set() and not collector.done:
        collector.take(timeout=0.1)
        status.show(time.monotonic(), collector.progress)


def _world_control(node: Node) -> str:
    """The world's name, as its world control's key has it (found once: the graph is asked no more per seed)."""
    world = next(iter(world_names(live_topics(node).values())), None)
    if world is None:
        raise ClientError("--randomise: no world control on the bus")
    return world


def _reset(node: Node, world: str, seed: int, timeout: float) -> None:
    """The world drawn from `seed`; ClientError naming the seed when the world cannot."""
    reply = node.call(f"world/{world}/control", {"reset": {"seed": seed}}, timeout=timeout + RESET_S)
    if not reply.get("ok"):
        raise ClientError(f"--randomise: seed {seed}: {reply.get('error')}")


def seeds(text: str) -> range:
    """`N` (seeds 0..N-1) or `FIRST:END` (FIRST..END-1)."""
    first, _, end = text.rpartition(":")
    try:
        span = range(int(first or 0), int(end))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or FIRST:END, whole numbers, got {text!r}") from None
    if not span or span.start < 0:
        raise argparse.ArgumentTypeError(f"expected at least one seed, all >= 0, got {text!r}")
    return span


def main(argv: Sequence[str] | None = None) -> int:
    """`simbot dataset --out DIR [--cameras KEY…] [--every N] [--count N] [--randomise SEEDS]`."""
    parser = client_parser(
        "simbot dataset",
        "Write synchronised camera frames (RGB, depth, label maps, boxes) with intrinsics and poses as a dataset.",
    )
    parser.add_argument("--out", required=True, type=Path, metavar="DIR", help="the dataset's folder (made if absent)")
    parser.add_argument(
        "--cameras", nargs="+", default=[], metavar="KEY", help="camera keys (default: every camera of the robot)"
    )
    parser.add_argument("--every", type=number(int), default=1, metavar="N", help="keep every Nth set (default 1)")
    parser.add_argument("--count", type=number(int), metavar="N", help="stop after N sets (default: until Ctrl-C)")
    parser.add_argument("--robot", metavar="NAME", help="the model carrying the cameras (default: the followed robot)")
    parser.add_argument(
        "--timeout", type=number(float), default=10.0, metavar="S", help="seconds to wait for the cameras (10)"
    )
    parser.add_argument(
        "--randomise",
        type=seeds,
        metavar="SEEDS",
        help="for each seed (N: 0..N-1, or FIRST:END) the world that seed draws, --count sets of each",
    )
    args = parser.parse_args(argv)
    if args.randomise is not None and args.count is None:
        parser.error("--randomise needs --count (the sets of each world)")
    return run_client(parser, argv, lambda args, node, stop: run(node, stop, _dataset_of(args)))


def _dataset_of(args: argparse.Namespace) -> Dataset:
    return Dataset(args.out, args.cameras, args.every, args.count, args.robot, args.timeout, args.randomise)


if __name__ == "__main__":
    sys.exit(main())
