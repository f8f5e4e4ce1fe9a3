"""Benchmark of what the cameras give visual odometry: an outside check with OpenCV, not the
renderer's own arithmetic.

`simbot-server` runs the warehouse in lockstep (every frame rendered at its exact sim time,
however loaded the machine is) with the cameras at 10 Hz; the tug drives a clockwise circle of
about 1.3 m radius round its start (0.3 m/s, −0.25 rad/s), which in 27 s turns the front camera
past every wall, the racks, the work cells, the pillars and always the floor. Per frame of
`camera_front`: ORB keypoints (`cv2.ORB_create(2000)`). Per pair of frames `GAP_S` apart:
matches (Hamming, cross-checked), `cv2.findEssentialMat` (RANSAC, 1 px) on the points undistorted
with the published K and D, `cv2.recoverPose`; the pair is tracked when recoverPose keeps at
least `MIN_INLIERS` points and its rotation is within `ROTATION_TOLERANCE_DEG` of the ground
truth from `model/flexley_tug/pose` (the camera is rigid on the body, so the optical frame turns
as the body does).

Why these thresholds: over `GAP_S` the camera turns about 7° and moves 15 cm. The 120° lens
gives f ≈ 185 px, so a pixel subtends 0.3°, and a rotation fitted to dozens of inliers at pixel
accuracy is good to a small fraction of that; 1° (3 px of image motion) leaves room for the
renderer's sampling, while a wrong fit (matches on a repeated pattern, the rotation/translation
ambiguity of a near-planar scene, the twisted-pair solution) is off by many degrees. Twenty
inliers are four times the five points an essential matrix needs, the least that outvotes chance
agreement among a few hundred matches.

    python benchmarks/bench_vo.py [--world PATH] [--seconds S]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from tables import publish

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port

from simbot.bus import BusOptions, Node, ServiceError, messages

WORLD = "warehouse"
CAMERA = "camera_front"
POSE = "model/flexley_tug/pose"
RATE_HZ = 10.0
STEPS_PER_FRAME = 100
"""1 kHz physics: one multi_step of 100 steps per 10 Hz frame."""
SPEED, TURN = 0.3, -0.25
GAP_S = 0.5
MIN_INLIERS = 20
ROTATION_TOLERANCE_DEG = 1.0
FEATURES = 2000
KEYPOINT_TARGET, TRACKED_TARGET = 1000, 0.97
OPTICAL_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Columns: the optical frame's x (right), y (down), z (forward) in the body frame (x forward, z up)."""

Gray = npt.NDArray[np.uint8]
Matrix = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Frame:
    stamp_ns: int
    gray: Gray
    camera_to_world: Matrix
    """Rotation of the optical frame in the world, from the ground-truth pose at the frame's stamp."""


@dataclass(frozen=True)
class Result:
    keypoints: list[int]
    tracked: list[bool]
    rotation_errors_deg: list[float]
    inliers: list[int]

    @property
    def median_keypoints(self) -> float:
        return float(statistics.median(self.keypoints))

    @property
    def tracked_share(self) -> float:
        return sum(self.tracked) / len(self.tracked)


class Inbox:
    """Messages of one topic from a Zenoh thread, kept under a lock."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._items: list[Any] = []

    def __call__(self, msg: Any) -> None:
        with self._lock:
            self._items.append(msg)

    def items(self) -> list[Any]:
        with self._lock:
            return list(self._items)


def _wait(condition: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(f"no {what} within {timeout:.0f} s")
        time.sleep(0.02)


@contextmanager
def lockstep_server(world: str, extra: tuple[str, ...] = ()) -> Iterator[Node]:
    """`simbot-server` in lockstep on a fresh loopback port and namespace, and a client node on it."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"vo_{uuid.uuid4().hex[:8]}"
    command = [sys.executable, "-m", "simbot.sim.server", "--world", world, "--mode", "lockstep", "--quiet"]
    command += ["--camera-rate", str(RATE_HZ), *extra, "--listen", endpoint, "--namespace", namespace]
    proc = subprocess.Popen(command, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"simbot-server exited with code {proc.returncode} at start")
            try:
                node = Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=1.0), "client")
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
        with node:
            _wait(lambda: _ready(node), 120, "answer from world control")
            yield node
    finally:
        proc.terminate()
        proc.wait(10)


def _call(node: Node, name: str, body: dict[str, Any]) -> dict[str, Any]:
    return node.call(f"world/{WORLD}/{name}", body, timeout=60.0)


def _ready(node: Node) -> bool:
    try:
        return bool(node.call(f"world/{WORLD}/state", {}, timeout=0.5).get("ok"))
    except (TimeoutError, ServiceError):
        return False


def _send(node: Node, topic: str, msg: Any) -> None:
    """Puts `msg` on an input of the server and waits until the server counts it received."""
    key = node.key(topic)
    before = _call(node, "state", {})["received"][key]
    node.publisher(topic, msg.__msgtype__, drop=False).put(msg)
    _wait(lambda: _call(node, "state", {})["received"][key] > before, 30, f"receipt of {topic}")


def drive(node: Node, seconds: float) -> tuple[list[Any], list[Any], Any]:
    """The route: images, ground-truth poses and the camera_info while the tug drives its circle."""
    images, poses, infos = Inbox(), Inbox(), Inbox()
    subscriptions = [
        node.subscribe(CAMERA, "sensor_msgs/msg/Image", images),
        node.subscribe(f"{CAMERA}/camera_info", "sensor_msgs/msg/CameraInfo", infos),
        node.subscribe(POSE, "geometry_msgs/msg/PoseStamped", poses),
    ]
    _send(node, "cmd_vel", messages.twist((SPEED, 0.0, 0.0), (0.0, 0.0, TURN)))
    for _ in range(round(seconds * RATE_HZ)):
        reply = _call(node, "control", {"multi_step": STEPS_PER_FRAME})
        if not reply.get("ok"):
            raise RuntimeError(f"multi_step refused: {reply}")
    frames = round(seconds * RATE_HZ) - 1
    _wait(lambda: len(images.items()) >= frames and infos.items(), 60, f"{frames} images of {CAMERA}")
    for subscription in subscriptions:
        subscription.close()
    return images.items(), poses.items(), infos.items()[-1]


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _rotation(q: Any) -> Matrix:
    """3×3 rotation of a geometry_msgs quaternion."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _body_rotation(poses: list[Any], stamp_ns: int) -> Matrix | None:
    """The body's rotation at `stamp_ns`: the pose of that stamp, else nlerp between the two around it."""
    stamps = [_stamp(p) for p in poses]
    after = int(np.searchsorted(stamps, stamp_ns))
    if after < len(stamps) and stamps[after] == stamp_ns:
        return _rotation(poses[after].pose.orientation)
    if after == 0 or after == len(stamps):
        return None
    a, b = poses[after - 1].pose.orientation, poses[after].pose.orientation
    qa, qb = np.array([a.x, a.y, a.z, a.w]), np.array([b.x, b.y, b.z, b.w])
    qb = qb if qa @ qb >= 0 else -qb
    s = (stamp_ns - stamps[after - 1]) / (stamps[after] - stamps[after - 1])
    q = (1 - s) * qa + s * qb
    q /= np.linalg.norm(q)
    return _rotation(messages.quaternion(*q))


def frames_of(images: list[Any], poses: list[Any]) -> list[Frame]:
    """Each image in grey with the optical frame's ground-truth rotation at its stamp."""
    poses = sorted(poses, key=_stamp)
    frames = []
    for image in sorted(images, key=_stamp):
        body = _body_rotation(poses, _stamp(image))
        if body is not None:
            gray = np.asarray(cv2.cvtColor(messages.image_pixels(image), cv2.COLOR_RGB2GRAY), np.uint8)
            frames.append(Frame(_stamp(image), gray, body @ OPTICAL_IN_BODY))
    return frames


def angle_deg(rotation: Matrix) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1.0, 1.0))))


def relative_pose(
    a: tuple[Any, Any], b: tuple[Any, Any], k: Matrix, d: Matrix, matcher: cv2.BFMatcher
) -> tuple[Matrix, int] | None:
    """recoverPose's rotation from frame a's camera to frame b's, and its inlier count (None: no fit)."""
    (kp_a, desc_a), (kp_b, desc_b) = a, b
    if desc_a is None or desc_b is None:
        return None
    matches = matcher.match(desc_a, desc_b)
    if len(matches) < 5:
        return None
    pa = np.array([kp_a[m.queryIdx].pt for m in matches], np.float64).reshape(-1, 1, 2)
    pb = np.array([kp_b[m.trainIdx].pt for m in matches], np.float64).reshape(-1, 1, 2)
    na, nb = cv2.undistortPoints(pa, k, d), cv2.undistortPoints(pb, k, d)
    eye = np.eye(3)
    essential, mask = cv2.findEssentialMat(na, nb, eye, cv2.RANSAC, 0.999, 1.0 / k[0, 0])
    if essential is None or essential.shape != (3, 3):
        return None
    inliers, rotation, _t, _mask = cv2.recoverPose(essential, na, nb, eye, mask=mask)
    return np.asarray(rotation, np.float64), int(inliers)


def evaluate(frames: list[Frame], info: Any) -> Result:
    """Keypoints per frame, and for each pair `GAP_S` apart whether it tracks."""
    orb = cv2.ORB_create(FEATURES)  # type: ignore[attr-defined]
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
    features = [orb.detectAndCompute(f.gray, None) for f in frames]
    k, d = np.array(info.k, np.float64).reshape(3, 3), np.array(info.d, np.float64)
    gap = round(GAP_S * RATE_HZ)
    tracked, errors, inliers = [], [], []
    for i in range(len(frames) - gap):
        a, b = frames[i], frames[i + gap]
        truth = b.camera_to_world.T @ a.camera_to_world
        fit = relative_pose(features[i], features[i + gap], k, d, matcher)
        error = angle_deg(fit[0].T @ truth) if fit else 180.0
        count = fit[1] if fit else 0
        tracked.append(count >= MIN_INLIERS and error <= ROTATION_TOLERANCE_DEG)
        errors.append(error)
        inliers.append(count)
    return Result([len(kp) for kp, _ in features], tracked, errors, inliers)


def measure(world: str, seconds: float) -> Result:
    with lockstep_server(world) as node:
        images, poses, info = drive(node, seconds)
    return evaluate(frames_of(images, poses), info)


def report(label: str, result: Result) -> None:
    """The figures of one run, ready for the README's table."""
    verdict = {True: "PASS", False: "NOT REACHED"}
    print(f"\n{label}: {len(result.keypoints)} frames, {len(result.tracked)} pairs {GAP_S} s apart")
    print(
        f"  ORB keypoints per frame: median {result.median_keypoints:.0f}, min {min(result.keypoints)}, "
        f"max {max(result.keypoints)} (target ≥ {KEYPOINT_TARGET}: "
        f"{verdict[result.median_keypoints >= KEYPOINT_TARGET]})"
    )
    print(
        f"  pairs tracked: {result.tracked_share:.1%} (target ≥ {TRACKED_TARGET:.0%}: "
        f"{verdict[result.tracked_share >= TRACKED_TARGET]}); recoverPose inliers median "
        f"{statistics.median(result.inliers):.0f}; rotation error median "
        f"{statistics.median(result.rotation_errors_deg):.2f}°, 95th percentile "
        f"{float(np.percentile(result.rotation_errors_deg, 95)):.2f}°"
    )


def table_of(label: str, result: Result) -> list[str]:
    """The docs' table: one row of this run, and the targets."""
    errors = result.rotation_errors_deg
    return [
        "| renderer and world | ORB keypoints per frame (median) | pairs tracked "
        "| rotation error, median / 95th percentile | recoverPose inliers (median) |",
        "| --- | --- | --- | --- | --- |",
        f"| {label} | {result.median_keypoints:.0f} | {result.tracked_share:.1%} "
        f"| {statistics.median(errors):.2f}° / {float(np.percentile(errors, 95)):.2f}° "
        f"| {statistics.median(result.inliers):.0f} |",
        f"| target | ≥ {KEYPOINT_TARGET} | ≥ {TRACKED_TARGET:.0%} | — | — |",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=WORLD, help="world name or SDF path (its <world> named warehouse)")
    parser.add_argument("--seconds", type=float, default=27.0, help="sim seconds of driving (27: one full circle)")
    args = parser.parse_args()
    label = f"{args.world}, {CAMERA}"
    result = measure(args.world, args.seconds)
    report(label, result)
    publish("vo", table_of(label, result))


if __name__ == "__main__":
    main()
