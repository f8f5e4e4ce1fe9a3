"""The camera stitcher as a process on a real server's bus (lockstep, six 160×120 cameras).

`tests/fixtures/stitcher_pole.sdf` stands a magenta pole 0.1 m thick and 2 m tall at
(2.4575, 1.7207): 3 m from base_link's axis (the default cylinder radius) at azimuth 35°, for
a robot spawned at the origin. camera_front (at (1, 0), yaw 0) sees it 49.7° left of its axis,
camera_front_left (at (1, 0.5), yaw 90°) 50.0° right of its axis, no other camera at all: it
stands on the seam between the two.

What is checked, and the tolerances:
- strip: 6 × 160 by 120, camera_info the front camera's; tile i is camera i's image, byte for
  byte; the pole is in tile 0 and tile 5 where the pinhole model puts its centre
  (u = cx + fx·x/z from the SPEC poses), ±1.5 px: the pole is 4 to 6 px wide and TinyRenderer
  draws it as a polygon, rasterised at pixel centres.
- cylindrical: 3 × 160 by 120, camera_info in base_link with fx = fy = W/2π, cx = (W−1)/2 and cy
  the row of base_link's z = 0. Each of the two cameras reprojected alone (the stitcher class,
  fed the very images, camera_info and tf_static the server published) puts the pole at the same
  column within 2 % of the width, and at its azimuth (u = cx − fx·35°) within 1.5 px (the pole
  is 2.5 px wide there); the stitcher process's own panorama shows it once, at that column in
  every row, from its foot to its top at the heights the cylinder gives them (±2 rows: a camera
  pixel there is about one panorama row, and bilinear interpolation spreads an edge by one more).
- partial sets: a robot whose camera_back publishes on another topic, and garbage (bytes that are
  no CDR Image, an image of an encoding the stitcher does not take) on `camera_back`: panoramas come
  out, black exactly over the sector that only camera_back sees (computed from the SPEC poses
  and the 120° field of view at the cameras' height), with a warning naming camera_back.
- each image before stitching: mono8 taken as grey; a size other than camera_info's, or data
  short of its rows, refused.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from client_helpers import client_command, client_process
from conftest import REPO, ROBOT_SDF
from server_helpers import TF_MESSAGE, SimServer, running_server, stamp_ns

from simbot.bus import messages
from simbot.bus.tf_tree import TransformTree
from simbot.clients.stitcher import (
    CAMERA_INFO,
    CAMERAS,
    IMAGE,
    BadInput,
    CameraModel,
    CylinderStitcher,
    Intrinsics,
    image_pixels,
)

WORLD = str(REPO / "tests" / "fixtures" / "stitcher_pole.sdf")
WIDTH, HEIGHT = 160, 120
SERVER_ARGS = ("--spawn", "0", "0", "0.1", "0", "--camera-size", f"{WIDTH}x{HEIGHT}")
FRAME_STEPS = 34  # one 30 Hz camera period in 1 ms steps
OUTPUT_TIMEOUT_S = 60.0

HFOV = 2.0944
FX = (WIDTH / 2) / math.tan(HFOV / 2)
CX, CY = (WIDTH - 1) / 2, (HEIGHT - 1) / 2
RADIUS = 3.0
CAMERA_Z = 0.39  # the cameras' height in base_link
BASE_LINK_Z = 0.0956 + 0.09  # base_footprint settled on its tyres + the chassis joint
# the cameras' positions in base_link and yaws (SPEC §1)
POSES = {
    "camera_front": (1.0, 0.0, 0.0),
    "camera_front_right": (1.0, -0.5, -math.pi / 2),
    "camera_back_right": (-1.0, -0.5, -math.pi / 2),
    "camera_back": (-1.0, 0.0, math.pi),
    "camera_back_left": (-1.0, 0.5, math.pi / 2),
    "camera_front_left": (1.0, 0.5, math.pi / 2),
}
POLE_AZIMUTH = math.radians(35.0)
POLE = (RADIUS * math.cos(POLE_AZIMUTH), RADIUS * math.sin(POLE_AZIMUTH))
POLE_HEIGHT = 2.0


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server(WORLD, "lockstep", extra=SERVER_ARGS) as server:
        yield server


def _pole(image: np.ndarray) -> np.ndarray:
    """Where the pole is: red and blue well above green, however it is shaded."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return (r - g > 60) & (b - g > 60)


def _pole_column(image: np.ndarray) -> float:
    """The mean column of the pole's pixels."""
    columns = np.nonzero(_pole(image))[1]
    assert columns.size, "no pole in the image"
    return float(columns.mean())


def _in_camera(name: str, x: float, y: float) -> tuple[float, float]:
    """(forward, left) of a base_link point (x, y) seen from a camera at its SPEC pose."""
    cx, cy, yaw = POSES[name]
    dx, dy = x - cx, y - cy
    return dx * math.cos(yaw) + dy * math.sin(yaw), -dx * math.sin(yaw) + dy * math.cos(yaw)


def _pinhole_column(name: str, x: float, y: float) -> float:
    forward, left = _in_camera(name, x, y)
    return CX - FX * left / forward  # optical x is to the right


def _sees(name: str, azimuth: float) -> bool:
    """Whether a camera sees the cylinder's point at `azimuth` at the cameras' height (u within the image)."""
    forward, left = _in_camera(name, RADIUS * math.cos(azimuth), RADIUS * math.sin(azimuth))
    return forward > 0 and abs(left) / forward <= (WIDTH / 2) / FX


def run_stitcher(
    sim: SimServer,
    *args: str,
    count: int = 3,
    each_chunk: Callable[[float], None] | None = None,
    robot: str = "",
    frame_steps: int = FRAME_STEPS,
) -> tuple[list[Any], list[Any], str]:
    """Runs the stitcher (following `robot`'s namespace, if given), stepping `frame_steps` (a camera
    period) at a time until `count` panoramas came out, and the last one's camera_info; (images,
    camera_infos, the stitcher's stderr once it has exited)."""
    out = f"{robot}/camera_360" if robot else "camera_360"
    images, infos = sim.subscribe(f"{out}/image_raw", IMAGE), sim.subscribe(f"{out}/camera_info", CAMERA_INFO)
    follow = ("--robot-namespace", robot) if robot else ()
    try:
        with client_process(sim, "stitcher", *follow, *args) as stitcher:
            deadline = time.monotonic() + OUTPUT_TIMEOUT_S
            while len(images) < count or len(infos) < count:
                assert stitcher.alive(), f"the stitcher exited: {stitcher.stderr()[-2000:]}"
                if time.monotonic() > deadline:
                    raise AssertionError(
                        f"{len(images)} panoramas in {OUTPUT_TIMEOUT_S} s: {stitcher.stderr()[-2000:]}"
                    )
                sim_time = sim.step(frame_steps)["sim_time"]
                if each_chunk is not None:
                    each_chunk(sim_time)
                before, wait_end = len(images), time.monotonic() + 0.3  # the stitcher runs on wall time
                while len(images) == before and time.monotonic() < wait_end:
                    time.sleep(0.01)
            shown = images.messages()  # the first may have come before the camera_info subscription did
            infos.wait_stamp(stamp_ns(shown[-1]), OUTPUT_TIMEOUT_S, "the last panorama's camera_info")
            assert stitcher.stop() == 0, stitcher.stderr()[-2000:]
            stderr = stitcher.stderr()
        return shown, infos.messages(), stderr
    finally:
        sim.unsubscribe_all()


def info_of(image: Any, infos: list[Any]) -> Any:
    """The camera_info published with `image` (the same stamp)."""
    return next(i for i in infos if messages.stamp_ns(i.header) == messages.stamp_ns(image.header))


def check_info(image: Any, info: Any, frame: str, k: tuple[float, float, float, float]) -> None:
    assert (info.width, info.height) == (image.width, image.height)
    assert info.header.frame_id == image.header.frame_id == frame
    assert messages.stamp_ns(info.header) == messages.stamp_ns(image.header)
    fx, fy, cx, cy = k
    assert np.allclose(info.k, [fx, 0, cx, 0, fy, cy, 0, 0, 1], atol=1e-9), info.k


def test_strip_is_the_six_images_side_by_side(sim: SimServer) -> None:
    raw = {name: sim.subscribe(name, IMAGE) for name in CAMERAS}  # the scene is static: every frame is the same
    images, infos, _ = run_stitcher(sim, "--layout", "strip")
    panorama, info = images[-1], info_of(images[-1], infos)
    assert (panorama.width, panorama.height, panorama.encoding) == (6 * WIDTH, HEIGHT, "rgb8")
    check_info(panorama, info, "camera_front_optical_frame", (FX, FX, CX, CY))
    pixels = messages.image_pixels(panorama)
    tiles = {name: pixels[:, i * WIDTH : (i + 1) * WIDTH] for i, name in enumerate(CAMERAS)}
    for name, tile in tiles.items():
        assert np.array_equal(tile, messages.image_pixels(raw[name].messages()[-1])), (
            f"the {name} tile is not its image"
        )
    for name in ("camera_front", "camera_front_left"):
        expected = _pinhole_column(name, *POLE)
        found = _pole_column(tiles[name])
        assert abs(found - expected) <= 1.5, (
            f"{name}: pole at column {found:.2f}, the pinhole model says {expected:.2f}"
        )
    for name in set(CAMERAS) - {"camera_front", "camera_front_left"}:
        assert not _pole(tiles[name]).any(), f"{name} cannot see the pole"


def _models(tf: Any, infos: dict[str, Any]) -> dict[str, CameraModel]:
    tree = TransformTree()
    tree.update(tf)
    models = {}
    for name, info in infos.items():
        intrinsics = Intrinsics.from_info(info)
        pose = tree.lookup("base_link", intrinsics.frame_id)
        assert pose is not None, f"tf_static does not place {intrinsics.frame_id}"
        models[name] = CameraModel.of(intrinsics, pose)
    return models


def test_cylinder_lines_the_pole_up_from_both_cameras(sim: SimServer) -> None:
    raw = {name: sim.subscribe(name, IMAGE) for name in CAMERAS}
    raw_infos = {name: sim.subscribe(f"{name}/camera_info", CAMERA_INFO) for name in CAMERAS}
    tf = sim.subscribe("tf_static", TF_MESSAGE, latched=True)
    images, infos, _ = run_stitcher(sim, "--layout", "cylindrical", "--radius", str(RADIUS))
    panorama, info = images[-1], info_of(images[-1], infos)
    width, height = 3 * WIDTH, HEIGHT
    f = width / (2 * math.pi)
    assert (panorama.width, panorama.height, panorama.encoding) == (width, height, "rgb8")
    check_info(panorama, info, "base_link", (f, f, (width - 1) / 2, (height - 1) / 2 + f * CAMERA_Z / RADIUS))
    expected_column = (width - 1) / 2 - f * POLE_AZIMUTH

    # each camera alone, reprojected by the stitcher's own class from what the server published
    models = _models(tf.messages()[-1], {name: c.messages()[-1] for name, c in raw_infos.items()})
    cylinder = CylinderStitcher(models, RADIUS)
    columns = {}
    for name in ("camera_front", "camera_front_left"):
        alone = cylinder.stitch({name: image_pixels(raw[name].messages()[-1])})
        columns[name] = _pole_column(alone)
        found = columns[name]
        assert abs(found - expected_column) <= 1.5, (
            f"{name} puts the pole at {found:.2f}, its azimuth at {expected_column:.2f}"
        )
    gap = abs(columns["camera_front"] - columns["camera_front_left"])
    assert gap <= 0.02 * width, f"the two cameras put the pole {gap:.2f} px apart"

    # the stitcher process's panorama: the pole once per row, at its azimuth, at its true heights
    pixels = messages.image_pixels(panorama)
    pole = _pole(pixels)
    rows = np.flatnonzero(pole.any(axis=1))
    for row in rows:
        run = np.flatnonzero(pole[row])
        assert run[-1] - run[0] <= 4, f"row {row}: the pole spreads over columns {run.tolist()} (shown twice?)"
        assert abs(run.mean() - expected_column) <= 1.5, (
            f"row {row}: pole at {run.mean():.2f}, expected {expected_column:.2f}"
        )
    top, foot = (info.k[5] - f * (z - BASE_LINK_Z) / RADIUS for z in (POLE_HEIGHT, 0.0))
    spans = f"the pole spans rows {rows[0]}..{rows[-1]}, expected {top:.1f}..{foot:.1f}"
    assert abs(rows[0] - top) <= 2 and abs(rows[-1] - foot) <= 2, spans
    centre_row = pixels[height // 2 - 1]
    assert not (centre_row == 0).all(axis=1).any(), "every azimuth is seen by some camera at the cameras' height"


def test_a_camera_missing_or_garbage_leaves_its_sector_black(tmp_path: Path) -> None:
    text = ROBOT_SDF.read_text()
    assert text.count("<topic>camera_back</topic>") == 1
    robot = tmp_path / "flexley_tug.sdf"
    unplugged = text.replace("<topic>camera_back</topic>", "<topic>camera_back_unplugged</topic>")
    robot.write_text(unplugged.replace("../meshes/", f"{REPO}/meshes/"))
    garbage = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)

    with running_server(WORLD, "lockstep", extra=(*SERVER_ARGS, "--robot", str(robot))) as server:

        def feed(sim_time: float) -> None:
            """On camera_back, which the server no longer publishes: undecodable bytes, and an image
            of an encoding the stitcher refuses."""
            server.send_raw("camera_back", "sensor_msgs/msg/Image", b"\x00\x01\x00\x00 not an image")
            image = messages.image(round(sim_time * 1e9), "camera_back_optical_frame", garbage)
            server.publisher("camera_back", "sensor_msgs/msg/Image").put(dataclasses.replace(image, encoding="32FC1"))

        images, infos, stderr = run_stitcher(server, count=4, each_chunk=feed)
    panorama = images[-1]
    assert (panorama.width, panorama.height) == (3 * WIDTH, HEIGHT) and len(infos) >= 4
    width = 3 * WIDTH
    f, cx = width / (2 * math.pi), (width - 1) / 2
    present = [name for name in CAMERAS if name != "camera_back"]
    expected = np.array([not any(_sees(name, (cx - u) / f) for name in present) for u in range(width)])
    black = (messages.image_pixels(panorama)[HEIGHT // 2 - 1] == 0).all(axis=1)
    edges = np.flatnonzero(np.diff(expected.astype(int))) + [[0], [1]]  # the columns either side of each sector edge
    differ = np.flatnonzero(black != expected)
    columns = f"black columns {np.flatnonzero(black).tolist()}, expected {np.flatnonzero(expected).tolist()}"
    assert set(differ) <= set(edges.reshape(-1)), columns
    assert expected.sum() > 60, "the test's geometry leaves camera_back a sector of its own"
    assert "camera_back: image skipped: encoding '32FC1'" in stderr, stderr[-2000:]
    assert "dropped a payload that is not a valid" in stderr, stderr[-2000:]


@pytest.mark.parametrize(("option", "value"), [("--radius", "-1"), ("--radius", "nan"), ("--layout", "fisheye")])
def test_bad_options_are_one_line_errors(option: str, value: str) -> None:
    command = client_command("stitcher", option, value)
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=60, cwd=REPO)
    assert result.returncode == 2, result.stderr
    assert option in result.stderr and "Traceback" not in result.stderr


def test_mono8_is_taken_as_grey_and_mismatched_images_are_refused() -> None:
    """What the loop does with each image before stitching it (no bus needed: the message as it arrives)."""
    grey = np.arange(WIDTH * HEIGHT, dtype=np.uint32).reshape(HEIGHT, WIDTH).astype(np.uint8)
    rgb = image_pixels(messages.image(0, "camera_front_optical_frame", grey), (WIDTH, HEIGHT))
    assert rgb.shape == (HEIGHT, WIDTH, 3) and all(np.array_equal(rgb[..., i], grey) for i in range(3))
    colour = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
    with pytest.raises(BadInput, match="image 160×120 but camera_info says 320×240"):
        image_pixels(messages.image(0, "camera_front_optical_frame", colour), (320, 240))
    short = dataclasses.replace(messages.image(0, "camera_front_optical_frame", colour), height=HEIGHT + 1)
    with pytest.raises(BadInput, match="cannot hold 121 rows"):
        image_pixels(short)
