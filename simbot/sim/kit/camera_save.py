"""Gazebo's `<save enabled="true"><path>P</path></save>` of a camera (under `<camera>`): every
frame the camera renders is written to P in simbot's dataset layout (simbot/dataset_format.py, the same
as `simbot dataset` writes), a relative P relative to the server's working directory, as Gazebo
does. Cameras saving to one folder share its manifest, their frames grouped by stamp.

A saving camera renders at its rate whether or not anyone subscribes. What it writes: its colour
(or mono) image, depth, and labels (a segmentation or bounding-box camera's, as label and
instance maps and COCO masks); a camera that renders none of these (thermal, wide-angle) saves
nothing, with a warning. Its pose is the optical frame's in the world where the frame was
rendered from (the frame carries it).
"""

from __future__ import annotations

import logging
from pathlib import Path

from simbot.bus.intrinsics import Intrinsics
from simbot.dataset_format import OPTICAL_IN_BODY, DatasetWriter, Shot, open_shared, release
from simbot.description.model import Param, Sensor
from simbot.sim.loop.system import SystemConfigError
from simbot.sim.render import CameraSpec, Frame
from simbot.sim.render.label_bits import instance_of, label_of, labelled
from simbot.transform import matmul

log = logging.getLogger(__name__)

ENABLED = ("true", "1")


def save_path(sensor: Sensor) -> Path | None:
    """The folder of an enabled `<save>`, or None; SystemConfigError when enabled without a `<path>`."""
    save = _child(_child(sensor.params, "camera"), "save")
    if save is None or dict(save.attrs).get("enabled", "false").strip().lower() not in ENABLED:
        return None
    path = next((p.text.strip() for p in save.children if p.tag == "path" and p.text.strip()), None)
    if path is None:
        raise SystemConfigError(f'sensor {sensor.name}: <camera><save enabled="true"> needs a <path>')
    return Path(path)


def _child(params: tuple[Param, ...] | Param | None, tag: str) -> Param | None:
    children = params.children if isinstance(params, Param) else params or ()
    return next((p for p in children if p.tag == tag), None)


SAVED = ("color", "mono", "depth", "labels")
"""The outputs a saving camera writes (as rgb, depth, labels and instances)."""


def frame_saver(sensor: Sensor, name: str, spec: CameraSpec) -> FrameSaver | None:
    """The saver of a camera whose `<save>` is enabled, else None; None with a warning for a camera
    that renders nothing the layout holds (a thermal or wide-angle image)."""
    path = save_path(sensor)
    if path is None:
        return None
    if not set(SAVED) & {kind.name for kind in spec.kinds}:
        log.warning("sensor %s: <save> writes colour, depth and labels; this camera renders none of them", sensor.name)
        return None
    return FrameSaver(path, name, spec)


class FrameSaver:
    """Writes a camera's frames with its intrinsics and ground-truth pose."""

    def __init__(self, path: Path, name: str, spec: CameraSpec) -> None:
        try:
            self.writer: DatasetWriter | None = open_shared(path)
        except OSError as exc:
            raise SystemConfigError(f"sensor {spec.name}: <camera><save><path> {path}: cannot write: {exc}") from None
        log.info("camera %s saves its frames to %s", spec.name, self.writer.root)
        self.name = name
        cx, cy = spec.principal_point
        self.intrinsics = Intrinsics(spec.width, spec.height, spec.fx, spec.fx, cx, cy, d=spec.distortion.d)

    def save(self, frame: Frame) -> None:
        """The frame's colour, depth and labels (each the camera renders), and the pose it was rendered from."""
        if self.writer is None:
            return
        body = frame.camera_pose
        shot = Shot(
            self.name, frame.stamp_ns, self.intrinsics, None if body is None else matmul(body.matrix(), OPTICAL_IN_BODY)
        )
        shot.color = frame.get("color", frame.get("mono"))
        shot.depth = frame.get("depth")
        if "labels" in frame:
            packed = frame["labels"]
            shot.instances = instance_of(packed) * labelled(packed)
            shot.labels = label_of(packed)
        try:
            self.writer.write([shot])
        except OSError as exc:
            log.error("camera %s stops saving: %s", self.name, exc)
            self.close()

    def close(self) -> None:
        """The folder's JSON files written out when the last camera saving there closes."""
        writer, self.writer = self.writer, None
        if writer is not None:
            try:
                release(writer)
            except OSError as exc:
                log.error("camera %s: %s: the manifest was not written: %s", self.name, writer.root, exc)
