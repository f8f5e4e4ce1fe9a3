"""Depth and RGBD cameras through the real server, with both renderers: REP 118 depth, the point
cloud, Gazebo's keys, one stamp for every product, and a camera of bad SDF left out with one line.

The world (tests/fixtures/depth_wall.sdf): a depth camera at (0, 0, 1) and an RGBD camera at
(0, 0.5, 1), both 160×120 with a 1.2 rad field of view, looking along +x at a wall whose near
face is the plane x = 3. z-depth along the optical axis is 3.00 m at every pixel (a range
reading would grow to 3/cos(0.6) = 3.63 m at the edges); the RGBD camera's points lie on the
plane z = 3 of its optical frame.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from server_helpers import SimServer, drawn_by, left_out, stamp_ns

from simbot.bus import messages

REPO = Path(__file__).resolve().parents[1]
WORLD = REPO / "tests" / "fixtures" / "depth_wall.sdf"
BEHIND = ["--spawn", "-10", "0", "0.1", "0"]
IMAGE, INFO, CLOUD = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/PointCloud2"
WALL = 3.0
W, H, HFOV = 160, 120, 1.2
FX = (W / 2) / math.tan(HFOV / 2)
FRAME_NS = 100_000_000  # the cameras' 10 Hz


@pytest.fixture(scope="module", params=["gl", "tiny"])
def sim(request: pytest.FixtureRequest) -> Iterator[SimServer]:
    with drawn_by(request.param, str(WORLD), BEHIND) as server:
        yield server


def test_depth_camera_reads_z_depth_of_the_wall_with_its_camera_info_beside_it(sim: SimServer) -> None:
    got = sim.latest({"depth_camera": IMAGE, "depth_camera/camera_info": INFO}, chunk=100)
    image, info = got["depth_camera"], got["depth_camera/camera_info"]
    assert (image.encoding, image.width, image.height, image.step) == ("32FC1", W, H, W * 4)
    assert image.header.frame_id == "depth_cam_optical_frame"
    depth = messages.depth_pixels(image)
    assert depth[H // 2, W // 2] == pytest.approx(WALL, abs=0.01)
    np.testing.assert_allclose(depth, WALL, atol=0.01)  # the plane z = 3 across the image: flat, not a range
    assert stamp_ns(info) == stamp_ns(image)
    assert info.k[0] == pytest.approx(FX) and info.k[2] == pytest.approx((W - 1) / 2)


def test_rgbd_camera_publishes_image_depth_points_and_info_under_one_stamp(sim: SimServer) -> None:
    topics = {"rgbd/image": IMAGE, "rgbd/depth_image": IMAGE, "rgbd/points": CLOUD, "rgbd/camera_info": INFO}
    collectors = {topic: sim.subscribe(topic, typename) for topic, typename in topics.items()}
    sim.prime(*collectors.values(), chunk=100, timeout=60.0)
    end_ns = round(sim.step(300)["sim_time"] * 1e9)  # lockstep: every frame of these steps is published by now
    for topic, collector in collectors.items():  # ...but one frame's products travel apart: wait for the last's
        collector.wait_for(lambda got: any(stamp_ns(m) > end_ns - FRAME_NS for m in got), 30.0, f"the last {topic}")
    stamps = {topic: {stamp_ns(m) for m in c.messages()} for topic, c in collectors.items()}
    latest = {topic: c.messages()[-1] for topic, c in collectors.items()}
    sim.unsubscribe_all()
    common = set.intersection(*stamps.values())
    assert len(common) >= 3 and all(len(s - common) <= 1 for s in stamps.values()), stamps
    rgb = messages.image_pixels(latest["rgbd/image"])
    assert (
        rgb.shape == (H, W, 3) and abs(int(rgb[H // 2, W // 2, 2]) - int(rgb[H // 2, W // 2, 0])) > 60
    )  # the wall is blue, not red
    np.testing.assert_allclose(messages.depth_pixels(latest["rgbd/depth_image"]), WALL, atol=0.01)
    cloud = latest["rgbd/points"]
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "rgb"] and (cloud.height, cloud.width) == (H, W)
    assert cloud.header.frame_id == "rgbd_cam_optical_frame"
    points = messages.point_cloud_array(cloud)
    np.testing.assert_allclose(points[..., 2], WALL, atol=0.01)  # every point on the wall within 1 cm
    u, v = np.meshgrid(np.arange(W) - (W - 1) / 2, np.arange(H) - (H - 1) / 2)
    np.testing.assert_allclose(points[..., 0], u * WALL / FX, atol=0.01)
    np.testing.assert_allclose(points[..., 1], v * WALL / FX, atol=0.01)
    packed = np.ascontiguousarray(points[..., 3]).view(np.uint32)[H // 2, W // 2]
    assert int(packed) == (int(rgb[H // 2, W // 2, 0]) << 16) | (int(rgb[H // 2, W // 2, 1]) << 8) | int(
        rgb[H // 2, W // 2, 2]
    )


BAD_CAMERAS = [
    (
        "<width>160</width><height>120</height><format>R_FLOAT32</format>",
        "<width>0</width><height>120</height>",
        "<width>",
    ),
    (
        "<width>160</width><height>120</height><format>R_FLOAT32</format>",
        "<width>100000</width><height>120</height>",
        "<width>",
    ),
    (
        "<horizontal_fov>1.2</horizontal_fov>\n            <image><width>160</width><height>120</height><format>R_FLOAT32",
        "<horizontal_fov>0</horizontal_fov>\n            <image><width>160</width><height>120</height><format>R_FLOAT32",
        "<horizontal_fov>",
    ),
    (
        "<horizontal_fov>1.2</horizontal_fov>\n            <image><width>160</width><height>120</height><format>R_FLOAT32",
        "<horizontal_fov>3.2</horizontal_fov>\n            <image><width>160</width><height>120</height><format>R_FLOAT32",
        "<horizontal_fov>",
    ),
    (
        "<near>0.1</near><far>10</far></clip>\n          </camera>\n        </sensor>\n      </link>",
        "<near>20</near><far>10</far></clip>\n          </camera>\n        </sensor>\n      </link>",
        "<near>",
    ),
    (
        "<width>160</width><height>120</height></image>",
        "<width>160</width><height>120</height><format>YUV_PLANAR</format></image>",
        "<format>",
    ),
    ("<width>160</width><height>120</height></image>", "<width>wide</width><height>120</height></image>", "<width>"),
]


@pytest.mark.parametrize(("good", "bad", "field"), BAD_CAMERAS)
def test_bad_camera_sdf_is_one_line_naming_the_sensor_and_field(
    tmp_path: Path, good: str, bad: str, field: str
) -> None:
    text = WORLD.read_text()
    assert good in text
    world = tmp_path / "bad.sdf"
    world.write_text(text.replace(good, bad, 1))
    (line,) = left_out(str(world), "depth_wall", *BEHIND)
    assert "sensor " in line and field in line, line
