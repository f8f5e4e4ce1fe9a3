"""Cameras through the real server: rendered in worker processes, published as rgb8 with true intrinsics.

The test world has one red box (1 m cube, near face at x 3.5) straight ahead of the front camera
of a robot spawned at the origin: the front camera (x 1.0, about 0.49 m up) sees it 2.5 m away,
centred, fx·1 m / 2.5 m = 74 px wide at 640 × 480 with the SDF's 120° field of view
(fx = 320 / tan 60° = 184.8 px). Every other camera looks at least 80° away from it, outside its
60° half field of view.
"""

from __future__ import annotations

import math
import os
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CAMERAS
from gl_helpers import NO_EGL
from server_helpers import SimServer, drawn_by, render_workers, running_server, stamp_ns, wait_until

from simbot.bus import messages

REPO = Path(__file__).resolve().parents[1]
WORLD = str(REPO / "tests" / "fixtures" / "camera_boxes.sdf")
AT_ORIGIN = ["--spawn", "0", "0", "0.1", "0"]
IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
HFOV = 2.0944
BOX_WIDTH, BOX_DISTANCE = 1.0, 2.5


@pytest.fixture(scope="module", params=["gl", "tiny"])
def sim(request: pytest.FixtureRequest) -> Iterator[SimServer]:
    """The geometry, intrinsics, stamps and rendering-on-demand tests run with each renderer."""
    with drawn_by(request.param, WORLD, AT_ORIGIN) as server:
        yield server


def _red(image: np.ndarray) -> np.ndarray:
    """Where the box is: red well above green and blue, whatever the shading."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return (r > 100) & (g < 60) & (b < 60)


def _first_frames(sim: SimServer, topics: tuple[str, ...], typename: str = IMAGE) -> dict[str, Any]:
    """The first subscription starts the render workers: a frame of each, 34 steps (a 30 Hz tick) at a time."""
    return sim.latest({topic: typename for topic in topics}, chunk=34)


def test_the_red_box_ahead_fills_the_front_image_and_no_other(sim: SimServer) -> None:
    frames = _first_frames(sim, CAMERAS)
    front = frames["camera_front"]
    assert (front.height, front.width, front.encoding, front.step) == (480, 640, "rgb8", 640 * 3)
    assert front.header.frame_id == "camera_front_optical_frame"
    image = messages.image_pixels(front)
    red = _red(image)
    assert red[240, 320] and red[235:245, 315:325].all(), (
        f"the centre of the front image is {image[240, 320]}, not the red box"
    )
    columns = np.flatnonzero(red[240])
    fx = 320 / math.tan(HFOV / 2)
    expected = fx * BOX_WIDTH / BOX_DISTANCE
    assert abs(len(columns) - expected) <= 3, (
        f"the box is {len(columns)} px wide, the pinhole model says {expected:.1f}"
    )
    assert abs((columns[0] + columns[-1]) / 2 - 319.5) <= 1.5, "the box is not centred"
    for name in CAMERAS[1:]:
        seen = int(_red(messages.image_pixels(frames[name])).sum())
        assert seen == 0, f"{name} sees {seen} red pixels of a box outside its field of view"


def test_camera_info_holds_the_intrinsics_of_the_fov(sim: SimServer) -> None:
    info = _first_frames(sim, ("camera_front/camera_info",), CAMERA_INFO)["camera_front/camera_info"]
    fx = 320 / math.tan(HFOV / 2)
    assert (info.width, info.height) == (640, 480) and info.header.frame_id == "camera_front_optical_frame"
    assert np.allclose(info.k, [fx, 0, 319.5, 0, fx, 239.5, 0, 0, 1], atol=1e-6)
    assert np.allclose(info.p, [fx, 0, 319.5, 0, 0, fx, 239.5, 0, 0, 0, 1, 0], atol=1e-6)
    assert np.allclose(info.r, np.eye(3).reshape(-1)) and not np.any(info.d)


def test_images_are_stamped_with_the_sim_time_they_show(sim: SimServer) -> None:
    """Driving forward 0.5 m/s, each frame's box width matches where ground truth put the robot at its stamp."""
    sim.reset()
    images = sim.subscribe("camera_front", IMAGE)
    poses = sim.subscribe("model/flexley_tug/pose", "geometry_msgs/msg/PoseStamped")
    sim.prime(images, poses, chunk=34, timeout=60.0)
    sim.drive(0.5)
    sim.step(2000)
    sim.drive(0.0)
    frames = images.wait_for(lambda items: stamp_ns(items[-1]) >= 2_000_000_000, timeout=30.0, what="frames up to 2 s")
    truth = {stamp_ns(p): p.pose.position.x for p in poses.messages()}
    checked = 0
    for frame in frames:
        x = truth.get(stamp_ns(frame))
        if x is None or x < 0.3:
            continue  # only stamps where the pose publisher (50 Hz) also has a sample, once clearly moving
        width = len(np.flatnonzero(_red(messages.image_pixels(frame))[240]))
        expected = (320 / math.tan(HFOV / 2)) * BOX_WIDTH / (3.5 - 1.0 - x)
        assert abs(width - expected) <= 3, (
            f"at {stamp_ns(frame) / 1e9:.3f} s (x {x:.3f}) the box is {width} px wide, expected {expected:.1f}"
        )
        checked += 1
    sim.unsubscribe_all()
    assert checked >= 5, "too few frames coincided with ground-truth poses"


def test_nobody_subscribed_nothing_rendered(sim: SimServer) -> None:
    """No image subscriber: frames are neither rendered nor counted; camera_info alone renders nothing."""
    before = sim.state()["sensors"]["flexley_tug/base_link/camera_back"]["messages"]
    _first_frames(sim, ("camera_back/camera_info",), CAMERA_INFO)
    sim.step(500)
    assert sim.state()["sensors"]["flexley_tug/base_link/camera_back"]["messages"] == before


def test_rates_over_five_seconds_in_lockstep() -> None:
    """Every camera 30 Hz (± 1 message over 5 s of sim time): lockstep renders every frame at its time."""
    with running_server(WORLD, "lockstep", extra=[*AT_ORIGIN, "--camera-size", "80x60"]) as sim:
        collectors = {topic: sim.subscribe(topic, IMAGE) for topic in CAMERAS}
        sim.prime(*collectors.values(), chunk=34, timeout=60.0)
        start = sim.state()["sim_time"]
        sim.step(5_000)
        end_ns = round((start + 5.0) * 1e9)
        for topic, collector in collectors.items():
            frames = collector.wait_for(
                lambda items: stamp_ns(items[-1]) >= end_ns - 34_000_000, timeout=60.0, what=f"{topic} up to {end_ns}"
            )
            stamps = [stamp_ns(m) for m in frames if start * 1e9 < stamp_ns(m) <= end_ns]
            assert abs(len(stamps) - 150) <= 1, f"{topic}: {len(stamps)} frames in 5 s"
            assert (frames[0].width, frames[0].height) == (80, 60)
        figures = sim.state()["sensors"]["flexley_tug/base_link/camera_front"]
        assert figures["rate_hz"] == pytest.approx(30.0, abs=0.5) and figures["skipped"] == 0, figures


def test_in_real_time_the_cameras_render_as_sets_sharing_a_stamp() -> None:
    """One render worker cannot keep six cameras at 30 Hz, so ticks are skipped, but always all six
    together: every stamp that reaches one camera reaches all six (what a stitcher pairs by).
    TinyRenderer, so that one worker surely falls behind."""
    with running_server(WORLD, "realtime", extra=[*AT_ORIGIN, "--render-workers", "1", "--renderer", "tiny"]) as sim:
        collectors = {topic: sim.subscribe(topic, IMAGE) for topic in CAMERAS}
        collectors["camera_front"].wait_count(6, timeout=60.0, what="camera_front images")
        stamps = {topic: {stamp_ns(m) for m in c.messages()} for topic, c in collectors.items()}
        settled = sorted(stamps["camera_front"])[1:-1]  # the first and last set may be in flight
        for topic, seen in stamps.items():
            missing = [s for s in settled if s not in seen]
            assert not missing, f"{topic} lacks the frames stamped {missing} that camera_front has"
        skipped = sim.state()["sensors"]["flexley_tug/base_link/camera_back"]["skipped"]
        assert skipped > 0, "one worker kept six cameras at 30 Hz: the test no longer shows sets being skipped together"


def test_every_image_has_its_camera_info_under_the_same_stamp_in_real_time() -> None:
    """All six cameras at 640×480 in real time, eleven frames each (however long a loaded machine
    takes to render them): each image's stamp has a camera_info with that stamp (what
    image_transport's CameraSubscriber and exact-time synchronisers pair)."""
    with running_server(WORLD, "realtime", extra=AT_ORIGIN) as sim:
        images = {topic: sim.subscribe(topic, IMAGE) for topic in CAMERAS}
        infos = {topic: sim.subscribe(f"{topic}/camera_info", CAMERA_INFO) for topic in CAMERAS}
        for topic in CAMERAS:
            images[topic].wait_count(11, timeout=120.0, what=f"{topic} images")
        for topic in CAMERAS:
            stamps = [stamp_ns(m) for m in images[topic].messages()][:-1]  # the last one's info may be in flight
            info_stamps = {stamp_ns(m) for m in infos[topic].messages()}
            missing = [s for s in stamps if s not in info_stamps]
            assert not missing, f"{topic}: {len(missing)} of {len(stamps)} images have no camera_info with their stamp"


def test_camera_rate_option_and_the_renderer_in_world_state() -> None:
    """--camera-rate 10 gives 10 Hz; world state names the renderer the default picked (gl where EGL opens)."""
    with running_server(
        WORLD, "lockstep", extra=[*AT_ORIGIN, "--camera-rate", "10", "--camera-size", "160x120"]
    ) as sim:
        images = sim.subscribe("camera_front", IMAGE)
        sim.prime(images, chunk=100, timeout=60.0)
        start = stamp_ns(images.messages()[-1])
        sim.step(1000)
        frames = images.wait_for(
            lambda items: stamp_ns(items[-1]) >= start + 1_000_000_000, timeout=30.0, what="1 s of frames"
        )
        assert len([m for m in frames if start < stamp_ns(m) <= start + 1_000_000_000]) == 10
        red = _red(messages.image_pixels(frames[-1]))
        assert red[60, 80], "the red box is not at the image centre"
        assert sim.state()["sensors"]["flexley_tug/base_link/camera_front"]["renderer"] == ("tiny" if NO_EGL else "gl")


def test_auto_falls_back_to_tiny_with_one_log_line_where_no_egl_context_opens(monkeypatch: pytest.MonkeyPatch) -> None:
    """No EGL vendor library: the server renders with TinyRenderer, logs why once, and the image is right."""
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl_vendor.json")
    with running_server(WORLD, "lockstep", extra=[*AT_ORIGIN, "--camera-size", "160x120"]) as sim:
        images = sim.subscribe("camera_front", IMAGE)
        sim.prime(images, chunk=100, timeout=60.0)
        assert _red(messages.image_pixels(images.messages()[-1]))[60, 80]
        assert sim.state()["sensors"]["flexley_tug/base_link/camera_front"]["renderer"] == "tiny"
        assert sim.stderr().count("cameras render with TinyRenderer: no OpenGL 3.3 EGL context") == 1, sim.stderr()


def test_bad_camera_options_are_one_line_errors() -> None:
    from subprocess import run

    from server_helpers import server_command

    for option, value in (
        ("--camera-size", "640by480"),
        ("--camera-size", "0x480"),
        ("--camera-rate", "-3"),
        ("--camera-rate", "nan"),
        ("--renderer", "egl"),
        ("--render-workers", "0"),
    ):
        result = run(server_command(option, value, "--world", "empty"), capture_output=True, text=True, timeout=30)
        assert result.returncode == 2, (option, value, result.stderr)
        assert option in result.stderr and "Traceback" not in result.stderr


def test_a_killed_render_worker_stops_the_cameras_not_the_simulation() -> None:
    """SIGKILL to the render workers (one on two cores, more on more): world state reports the front camera's
    error, and sim time and odom go on."""
    with running_server(WORLD, "realtime", extra=[*AT_ORIGIN, "--camera-size", "160x120"]) as sim:
        images = sim.subscribe("camera_front", IMAGE)
        images.wait_count(3, timeout=60.0, what="camera_front images")
        workers = render_workers(sim.process.pid)
        assert workers, "no render worker while camera_front renders"
        for worker in workers:
            os.kill(worker, signal.SIGKILL)
        front = "flexley_tug/base_link/camera_front"
        wait_until(lambda: "error" in sim.state()["sensors"][front], 30.0, "the camera's error in world state")
        assert "died" in sim.state()["sensors"][front]["error"]
        killed_at = sim.state()["sim_time"]
        odom = sim.subscribe("odom", "nav_msgs/msg/Odometry")
        odom.wait_count(25, timeout=30.0, what="odom after the worker died")  # 50 Hz: half a second
        assert sim.alive() and sim.state()["sim_time"] >= killed_at + 0.4
