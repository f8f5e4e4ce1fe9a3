"""A camera dataset on disk, in a layout a training script reads without glue: written by
`simbot dataset` (clients/dataset.py) from the bus, and by a camera whose SDF says
`<save enabled="true">` (simbot/sim/systems/camera.py) from the server. One writer, so the two
layouts are the same.

    DIR/manifest.json                    every set of frames (one stamp), every frame's files,
                                         camera, stamp, intrinsics and ground-truth pose
    DIR/annotations.json                 COCO: an image per annotated frame, its instance masks
                                         (uncompressed RLE) and boxes, categories = labels
    DIR/<camera>/rgb/<stamp>.png         colour (8-bit RGB) or mono8 (8-bit grey)
    DIR/<camera>/depth/<stamp>.png       depth: 16-bit grey, millimetres along the optical axis;
                                         0 = no reading (nothing within the far clip, or > 65.535 m)
    DIR/<camera>/labels/<stamp>.png      8-bit grey: each pixel's label (category)
    DIR/<camera>/instances/<stamp>.png   16-bit grey: each pixel's instance (0: background)

`<camera>` is the camera's key (its slashes make folders), `<stamp>` its frame's stamp in
nanoseconds of sim time, 19 digits, so that names sort by time; a frame of a randomised world
(`simbot dataset --randomise`) is `<seed>-<stamp>.png`, its seed in 10 digits, and its set in the
manifest says `world_seed`. A pose is the camera's optical
frame (z forward, x right, y down: the frame its intrinsics K project from) in the world, as a
4×4 matrix mapping points of the optical frame into the world. A COCO image's `file_name` is the
colour image of the same set taken from the same place with the same intrinsics (a colour camera
beside a segmentation camera), else the frame's own first file.

The JSON files are rewritten whole (to a temporary name, then renamed, so a reader never sees
half a file) at most once per `flush_period_s` and on `close`.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from simbot.bus.intrinsics import Intrinsics

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
COCO = "annotations.json"
FORMAT = "simbot-dataset/1"
MM_PER_M = 1000.0
MAX_DEPTH_MM = 65535
SAME_PLACE_M = 1e-6
"""How far apart two cameras may be and still count as one viewpoint (the colour image of a mask)."""

Matrix = npt.NDArray[np.float64]
OPTICAL_IN_BODY: Matrix = np.array([[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0, 0, 0, 1.0]])
"""A camera's optical frame (z forward, x right, y down) in its body frame (x forward, z up):
simbot.bus.frames.OPTICAL_RPY as a matrix."""


@dataclass(frozen=True)
class Box:
    """A detected box in pixels (COCO's convention: top-left corner, width, height) and its label."""

    label: int
    x: float
    y: float
    width: float
    height: float


@dataclass
class Shot:
    """One camera's frame: what it shows, when, with what intrinsics and from where."""

    camera: str
    stamp_ns: int
    intrinsics: Intrinsics | None = None
    pose: Matrix | None = None
    """4×4: the optical frame in the world; None when no ground truth was found."""
    color: npt.NDArray[np.uint8] | None = None
    """H×W×3 rgb or H×W grey."""
    depth: npt.NDArray[np.float32] | None = None
    """Metres along the optical axis, +inf or NaN where nothing was seen."""
    instances: npt.NDArray[np.uint16] | None = None
    """Each pixel's instance, 0 for background (with `labels`)."""
    labels: npt.NDArray[np.uint8] | None = None
    boxes: Sequence[Box] | None = None
    world_seed: int | None = None
    """The seed of the randomised world it shows (simbot.variation), None for the world as its file says:
    a stamp recurs in each world, so the seed leads its file names and its set's key."""


@dataclass
class _Frame:
    """A written frame, as the manifest and COCO name it."""

    shot: Shot
    files: dict[str, str]
    annotations: list[dict[str, Any]] = field(default_factory=list)


class DatasetWriter:
    """Writes sets of shots under `root` (see the module docstring). Raises OSError when `root`
    cannot be created or written."""

    def __init__(self, root: Path, flush_period_s: float = 1.0) -> None:
        self.root = root
        self.flush_period_s = flush_period_s
        self.sets: dict[tuple[int, int], list[_Frame]] = {}
        """By (world seed, or -1, and stamp)."""
        self.categories: set[int] = set()
        self._next_flush = 0.0
        root.mkdir(parents=True, exist_ok=True)
        self._write_json(MANIFEST, self.manifest())

    def write(self, shots: Sequence[Shot]) -> None:
        """The shots' files now; their set (by stamp, joining frames already written at that stamp) in
        the JSON files at the next flush."""
        for shot in shots:
            frame = _Frame(shot, self._write_images(shot))
            frame.annotations = annotations_of(shot)
            self.categories.update(a["category_id"] for a in frame.annotations)
            self.sets.setdefault((-1 if shot.world_seed is None else shot.world_seed, shot.stamp_ns), []).append(frame)
        if time.monotonic() >= self._next_flush:
            self.flush()

    def flush(self) -> None:
        self._next_flush = time.monotonic() + self.flush_period_s
        self._write_json(MANIFEST, self.manifest())
        self._write_json(COCO, self.coco())

    close = flush

    def _write_images(self, shot: Shot) -> dict[str, str]:
        world = "" if shot.world_seed is None else f"{shot.world_seed:010d}-"
        stamp = f"{world}{shot.stamp_ns:019d}.png"
        files: dict[str, str] = {}
        for kind, pixels in _images(shot):
            relative = f"{shot.camera.strip('/')}/{kind}/{stamp}"
            path = self.root / relative
            path.parent.mkdir(parents=True, exist_ok=True)
            ok, png = cv2.imencode(".png", pixels)
            if not ok:
                raise OSError(f"{path}: PNG encoding failed")
            path.write_bytes(png.tobytes())
            files[kind] = relative
        return files

    def _write_json(self, name: str, content: dict[str, Any]) -> None:
        path = self.root / name
        partial = path.with_name(f".{name}.partial")
        partial.write_text(json.dumps(content, indent=1))
        os.replace(partial, path)

    def manifest(self) -> dict[str, Any]:
        ids = self._image_ids()
        return {
            "format": FORMAT,
            "depth": {"encoding": "png 16-bit", "unit": "mm", "no_reading": 0},
            "pose": "4x4 matrix: the camera's optical frame (z forward, x right, y down) in the world",
            "coco": COCO,
            "sets": [
                {"stamp_ns": stamp, "frames": [_frame_json(f, ids.get(id(f))) for f in frames]}
                | ({} if seed < 0 else {"world_seed": seed})
                for (seed, stamp), frames in sorted(self.sets.items())
            ],
        }

    def coco(self) -> dict[str, Any]:
        images: list[dict[str, Any]] = []
        annotations: list[dict[str, Any]] = []
        ids = self._image_ids()
        for frames in self.sets.values():
            for frame in frames:
                if id(frame) not in ids:
                    continue
                image_id = ids[id(frame)]
                images.append(_coco_image(image_id, frame, frames))
                for annotation in frame.annotations:
                    annotations.append(annotation | {"id": len(annotations) + 1, "image_id": image_id})
        return {
            "info": {"description": "simbot camera dataset", "version": FORMAT},
            "images": images,
            "annotations": annotations,
            "categories": [{"id": label, "name": str(label)} for label in sorted(self.categories)],
        }

    def _image_ids(self) -> dict[int, int]:
        """COCO image ids (1, 2, ...) of the frames that carry annotations, in stamp order."""
        annotated = [
            frame
            for _, frames in sorted(self.sets.items())
            for frame in frames
            if frame.shot.instances is not None or frame.shot.boxes is not None
        ]
        return {id(frame): number for number, frame in enumerate(annotated, start=1)}


def _images(shot: Shot) -> list[tuple[str, npt.NDArray[Any]]]:
    """(kind, pixels as OpenCV writes them) of each image the shot holds."""
    images: list[tuple[str, npt.NDArray[Any]]] = []
    if shot.color is not None:
        color = shot.color
        images.append(("rgb", cv2.cvtColor(color, cv2.COLOR_RGB2BGR) if color.ndim == 3 else color))
    if shot.depth is not None:
        images.append(("depth", depth_mm(shot.depth)))
    if shot.labels is not None:
        images.append(("labels", shot.labels))
    if shot.instances is not None:
        images.append(("instances", shot.instances))
    return images


def depth_mm(depth: npt.NDArray[np.float32]) -> npt.NDArray[np.uint16]:
    """Metres to whole millimetres; 0 where there is no reading or it does not fit 16 bits."""
    mm = np.asarray(depth, dtype=np.float64) * MM_PER_M
    valid = np.isfinite(mm) & (mm > 0) & (mm <= MAX_DEPTH_MM)
    return np.where(valid, np.rint(np.where(valid, mm, 0)), 0).astype(np.uint16)


def annotations_of(shot: Shot) -> list[dict[str, Any]]:
    """COCO annotations (without ids) of a shot: a mask per (instance, label) of its label map,
    else a box per detection."""
    if shot.instances is not None and shot.labels is not None:
        return mask_annotations(shot.instances, shot.labels)
    return [
        {"category_id": b.label, "bbox": [b.x, b.y, b.width, b.height], "area": b.width * b.height, "iscrowd": 0}
        for b in shot.boxes or ()
    ]


def mask_annotations(instances: npt.NDArray[np.uint16], labels: npt.NDArray[np.uint8]) -> list[dict[str, Any]]:
    """One annotation per (instance, label) pair seen: its mask in uncompressed RLE, area and box."""
    key = (instances.astype(np.uint32) << 8) | labels
    found = np.unique(key[instances != 0])
    out = []
    for value in found.tolist():
        mask = key == value
        out.append(
            {
                "category_id": value & 0xFF,
                "instance": value >> 8,
                "segmentation": rle(mask),
                "area": int(mask.sum()),
                "bbox": mask_box(mask),
                "iscrowd": 0,
            }
        )
    return out


def rle(mask: npt.NDArray[np.bool_]) -> dict[str, Any]:
    """COCO's uncompressed run-length encoding: runs down the columns (Fortran order), the first a
    run of zeros (0 long when the first pixel is set)."""
    flat = np.asarray(mask, dtype=bool).ravel(order="F")
    edges = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    counts = np.diff(np.concatenate(([0], edges, [flat.size]))).tolist()
    if flat.size and flat[0]:
        counts.insert(0, 0)
    return {"size": [int(mask.shape[0]), int(mask.shape[1])], "counts": counts}


def mask_box(mask: npt.NDArray[np.bool_]) -> list[float]:
    """The mask's box as COCO (and pycocotools' toBbox) gives it: x, y of the top-left pixel, width, height in pixels."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    x0, y0 = int(cols[0]), int(rows[0])
    return [float(x0), float(y0), float(cols[-1] - x0 + 1), float(rows[-1] - y0 + 1)]


def _frame_json(frame: _Frame, image_id: int | None) -> dict[str, Any]:
    shot = frame.shot
    return {
        "camera": shot.camera,
        "stamp_ns": shot.stamp_ns,
        "files": frame.files,
        "intrinsics": None if shot.intrinsics is None else shot.intrinsics.to_json(),
        "pose": None if shot.pose is None else np.asarray(shot.pose).tolist(),
        "coco_image_id": image_id,
    }


def _coco_image(image_id: int, frame: _Frame, set_frames: Sequence[_Frame]) -> dict[str, Any]:
    shot = frame.shot
    height, width = _size(shot)
    return {
        "id": image_id,
        "file_name": _picture(frame, set_frames),
        "width": width,
        "height": height,
        "camera": shot.camera,
        "stamp_ns": shot.stamp_ns,
    }


def _size(shot: Shot) -> tuple[int, int]:
    for pixels in (shot.instances, shot.color, shot.depth):
        if pixels is not None:
            return int(pixels.shape[0]), int(pixels.shape[1])
    intrinsics = shot.intrinsics
    return (intrinsics.height, intrinsics.width) if intrinsics is not None else (0, 0)


def _picture(frame: _Frame, set_frames: Sequence[_Frame]) -> str:
    """The colour image that shows what the frame annotates: one of the same set from the same
    viewpoint, else the frame's own first file."""
    for other in set_frames:
        if "rgb" in other.files and _same_view(frame.shot, other.shot):
            return other.files["rgb"]
    return next(iter(frame.files.values()), "")


def _same_view(a: Shot, b: Shot) -> bool:
    if a is b:
        return True
    if a.pose is None or b.pose is None or a.intrinsics != b.intrinsics:
        return False
    return bool(np.allclose(a.pose, b.pose, atol=SAME_PLACE_M))


_SHARED: dict[Path, tuple[DatasetWriter, int]] = {}
"""The writers of one process by folder: cameras saving to one folder share one manifest."""


def open_shared(root: Path) -> DatasetWriter:
    """The process's writer of `root`, made on first use; each call is matched by `release`."""
    root = root.resolve()
    writer, users = _SHARED.get(root) or (DatasetWriter(root), 0)
    _SHARED[root] = (writer, users + 1)
    return writer


def release(writer: DatasetWriter) -> None:
    """One user less; the last closes the writer (the JSON files written out)."""
    held, users = _SHARED[writer.root]
    if users > 1:
        _SHARED[writer.root] = (held, users - 1)
        return
    del _SHARED[writer.root]
    writer.close()
