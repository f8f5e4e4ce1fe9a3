"""Benchmark of the camera stitcher: one set of six 640×480 images stitched per call, each layout
against the bare OpenCV/numpy operation it is built on, measured in the same run.

1. strip: `StripStitcher.stitch` (each image copied into its tile of a reused buffer) against
   `np.hstack` of the six images;
2. cylindrical: `CylinderStitcher.stitch` (the tiles filled, then one `cv2.remap` through the
   fixed-point tables) against a bare `cv2.remap` of a 3840×480 source to the same 1920×480
   output through the same tables, and against `np.hstack` of the six followed by that remap
   (the same work in bare numpy and OpenCV); and, for what the fixed-point tables buy, the same
   remap through float32 tables;
3. what a set costs the client beyond the stitch: the panorama into a sensor_msgs/Image and CDR
   (`messages.image` + `encode`), against a bare `bytes()` copy of the panorama;
4. the one-off cost of the cylinder's tables (once per camera geometry and set of cameras).

The cameras are the Tug's (SPEC §1: 120° field of view, poses on base_link at z 0.39), the
images random pixels (the cost does not depend on what they show). Each figure is the median of
many calls: one preemption on a shared machine is not a cost.

    python benchmarks/bench_stitcher.py [--calls N]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Callable

import cv2
import numpy as np
from tables import publish

from simbot.bus import encode, messages
from simbot.bus.frames import OPTICAL_RPY, optical_frame
from simbot.clients.stitcher import (
    CAMERAS,
    DEFAULT_RADIUS_M,
    CameraModel,
    CylinderStitcher,
    Intrinsics,
    Pixels,
    StripStitcher,
)
from simbot.description.poses import Pose

WIDTH, HEIGHT = 640, 480
HFOV = 2.0944
CAMERA_Z = 0.39
TARGET_MS = 15.0
MOUNTS = {
    "camera_front": (1.0, 0.0, 0.0),
    "camera_front_right": (1.0, -0.5, -math.pi / 2),
    "camera_back_right": (-1.0, -0.5, -math.pi / 2),
    "camera_back": (-1.0, 0.0, math.pi),
    "camera_back_left": (-1.0, 0.5, math.pi / 2),
    "camera_front_left": (1.0, 0.5, math.pi / 2),
}
"""Each camera's body frame on base_link (SPEC §1): x, y, yaw."""


def tug_cameras() -> dict[str, CameraModel]:
    """The six cameras as the stitcher sees them from camera_info and tf_static."""
    fx = (WIDTH / 2) / math.tan(HFOV / 2)
    models = {}
    for name, (x, y, yaw) in MOUNTS.items():
        intrinsics = Intrinsics(WIDTH, HEIGHT, fx, fx, (WIDTH - 1) / 2, (HEIGHT - 1) / 2, frame_id=optical_frame(name))
        pose = Pose((x, y, CAMERA_Z), (0.0, 0.0, yaw)).matrix() @ Pose(rpy=OPTICAL_RPY).matrix()
        models[name] = CameraModel.of(intrinsics, pose)
    return models


def paired_ms(work: Callable[[], object], bare: Callable[[], object], calls: int) -> tuple[float, float]:
    """Median milliseconds of one call of `work` and of `bare`, called in turn (so that a busy spell
    of a shared machine falls on both alike), after a few warm-up calls."""
    for _ in range(3):
        work()
        bare()
    times: tuple[list[float], list[float]] = ([], [])
    for _ in range(calls):
        for fn, out in ((work, times[0]), (bare, times[1])):
            start = time.perf_counter()
            fn()
            out.append(time.perf_counter() - start)
    return statistics.median(times[0]) * 1e3, statistics.median(times[1]) * 1e3


def verdict(ms: float) -> str:
    return "met" if ms < TARGET_MS else "MISSED"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200, help="calls per measurement (default 200)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    images: dict[str, Pixels] = {name: rng.integers(0, 256, (HEIGHT, WIDTH, 3), dtype=np.uint8) for name in CAMERAS}
    ordered = [images[name] for name in CAMERAS]
    models = tug_cameras()

    strip = StripStitcher({name: m.intrinsics for name, m in models.items()})
    strip_ms, hstack_ms = paired_ms(lambda: strip.stitch(images), lambda: np.hstack(ordered), args.calls)

    start = time.perf_counter()
    cylinder = CylinderStitcher(models, DEFAULT_RADIUS_M)
    map1, map2 = cylinder.tables(frozenset(CAMERAS))
    tables_ms = (time.perf_counter() - start) * 1e3
    source = np.hstack(ordered)
    out = np.empty((cylinder.height, cylinder.width, 3), dtype=np.uint8)

    def bare_remap() -> None:
        cv2.remap(source, map1, map2, cv2.INTER_LINEAR, dst=out)

    def bare_stitch() -> None:
        cv2.remap(np.hstack(ordered), map1, map2, cv2.INTER_LINEAR, dst=out)

    cylinder_ms, remap_ms = paired_ms(lambda: cylinder.stitch(images), bare_remap, args.calls)
    cylinder_again_ms, hstack_remap_ms = paired_ms(lambda: cylinder.stitch(images), bare_stitch, args.calls)
    partial = {name: image for name, image in images.items() if name != "camera_back"}
    partial_map1, partial_map2 = cylinder.tables(frozenset(partial))
    without_back = [image if name in partial else np.zeros_like(image) for name, image in zip(CAMERAS, ordered)]

    def bare_partial() -> None:
        cv2.remap(np.hstack(without_back), partial_map1, partial_map2, cv2.INTER_LINEAR, dst=out)

    partial_ms, partial_bare_ms = paired_ms(lambda: cylinder.stitch(partial), bare_partial, args.calls)
    map_x, map_y = cylinder.source_coordinates(frozenset(CAMERAS))
    float_ms, fixed_ms = paired_ms(
        lambda: cv2.remap(source, map_x, map_y, cv2.INTER_LINEAR, dst=out), bare_remap, args.calls
    )

    panorama = cylinder.stitch(images)
    info = cylinder.info
    message_ms, copy_ms = paired_ms(
        lambda: encode(messages.image(0, info.frame_id, panorama)), lambda: bytes(panorama), args.calls
    )

    rows = [
        (
            f"strip: six {WIDTH}×{HEIGHT} → {strip.width}×{strip.height}",
            f"{strip_ms:.2f} ms = {strip_ms / hstack_ms:.2f}× bare ({verdict(strip_ms)})",
            f"< {TARGET_MS:.0f} ms",
            f"np.hstack of the six: {hstack_ms:.2f} ms",
        ),
        (
            f"cylindrical: six {WIDTH}×{HEIGHT} → {cylinder.width}×{cylinder.height}",
            f"{cylinder_ms:.2f} ms = {cylinder_ms / remap_ms:.2f}× bare ({verdict(cylinder_ms)})",
            f"< {TARGET_MS:.0f} ms",
            f"one cv2.remap {source.shape[1]}×{source.shape[0]} → {cylinder.width}×{cylinder.height},"
            f" same fixed-point tables: {remap_ms:.2f} ms",
        ),
        (
            "cylindrical, the same, measured again",
            f"{cylinder_again_ms:.2f} ms = {cylinder_again_ms / hstack_remap_ms:.2f}× bare"
            f" ({verdict(cylinder_again_ms)})",
            f"< {TARGET_MS:.0f} ms",
            f"np.hstack of the six, then that cv2.remap: {hstack_remap_ms:.2f} ms",
        ),
        (
            "cylindrical, camera_back missing (its tables cached)",
            f"{partial_ms:.2f} ms = {partial_ms / partial_bare_ms:.2f}× bare ({verdict(partial_ms)})",
            f"< {TARGET_MS:.0f} ms",
            f"np.hstack + cv2.remap through the same five-camera tables: {partial_bare_ms:.2f} ms",
        ),
        (
            "the same remap through float32 tables",
            f"{float_ms:.2f} ms = {float_ms / fixed_ms:.2f}× fixed-point",
            "—",
            f"fixed-point tables: {fixed_ms:.2f} ms",
        ),
        (
            f"panorama {cylinder.width}×{cylinder.height} → sensor_msgs/Image → CDR",
            f"{message_ms:.2f} ms = {message_ms / copy_ms:.2f}× bare",
            "—",
            f"bytes() of the panorama: {copy_ms:.2f} ms",
        ),
        ("cylinder tables, once per camera geometry", f"{tables_ms:.0f} ms", "—", "—"),
    ]
    header = ["| measurement | result | target | baseline in the same run |", "| --- | --- | --- | --- |"]
    publish("stitcher", header + ["| " + " | ".join(row) + " |" for row in rows])
    cores = len(os.sched_getaffinity(0))
    print(
        f"\nmedians of {args.calls} calls; OpenCV {cv2.__version__} with {cv2.getNumThreads()} threads on {cores} cores"
    )


if __name__ == "__main__":
    main()
