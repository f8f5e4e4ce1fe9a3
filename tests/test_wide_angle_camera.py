"""The wide-angle camera (SDF `wideanglecamera`) through the real server: Gazebo's lens mapping,
drawn as a remap of cube faces, published with camera_info; a bad lens is one line and the world runs.

The test world (written here) has a rig 1 m up at the origin looking along +x with two 320 × 240
equidistant cameras of 180° (scale_to_hfov: f = 160 px / (π/2) = 101.86 px a radian): `fisheye`
(cut off at 90°) and `cut` (cut off at 1.0 rad), a third whose lens type is not Gazebo's and a
fourth whose custom function is not. Three
0.4 m boxes lie 3 m from the rig: red straight ahead, green 80° to the left, blue 40° up. An
equidistant lens puts a direction θ off the axis at f·θ from the image centre, along its azimuth:
the green box at 142 px left of centre, the blue one 71 px above it. A box spans about 8° (14 px),
so its colour's centroid lies on its centre's direction to well under a pixel (the lens's radial
stretch across it is symmetric to first order); ±2 px allows for the cube faces' pixel grid
(256 px a face: 0.45 mrad a pixel at a face's centre, finer than the image's 9.8 mrad).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from gz_examples import gazebo_example
from server_helpers import SimServer, drawn_by, running_server

from simbot.sim.render.wide_lens import LENS_TYPES, WideLens
from simbot.sim.systems.wide_angle_camera import info_model

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
WIDTH, HEIGHT = 320, 240
FOCAL = (WIDTH / 2) / (math.pi / 2)
DISTANCE, HEIGHT_M = 3.0, 1.0
BEHIND = ["--spawn", "-10", "0", "0.1", "0"]

BOXES = {
    "red": ((1.0, 0.0, 0.0), 0.0, 0.0),
    "green": ((0.0, 1.0, 0.0), math.radians(80.0), 0.0),
    "blue": ((0.0, 0.0, 1.0), 0.0, math.radians(40.0)),
}
"""Colour → (rgb, azimuth to the left, elevation) of each box seen from the rig."""


def _sensor(name: str, lens: str) -> str:
    return f"""<sensor name="{name}" type="wideanglecamera">
      <update_rate>10</update_rate><topic>{name}</topic>
      <camera><horizontal_fov>3.14159265</horizontal_fov>
        <image><width>{WIDTH}</width><height>{HEIGHT}</height></image>
        <clip><near>0.1</near><far>20</far></clip><lens>{lens}</lens></camera></sensor>"""


def _box(name: str, rgb: tuple[float, ...], azimuth: float, elevation: float) -> str:
    x = DISTANCE * math.cos(elevation) * math.cos(azimuth)
    y = DISTANCE * math.cos(elevation) * math.sin(azimuth)
    z = HEIGHT_M + DISTANCE * math.sin(elevation)
    colour = " ".join(map(str, (*rgb, 1)))
    return f"""<model name="{name}"><static>true</static><pose>{x} {y} {z} 0 0 {azimuth}</pose>
      <link name="link"><visual name="v"><geometry><box><size>0.4 0.4 0.4</size></box></geometry>
      <material><ambient>{colour}</ambient><diffuse>{colour}</diffuse></material></visual></link></model>"""


def world_text() -> str:
    lens = "<type>equidistant</type><env_texture_size>256</env_texture_size><cutoff_angle>{}</cutoff_angle>"
    sensors = (
        _sensor("fisheye", lens.format(math.pi / 2))
        + _sensor("cut", lens.format(1.0))
        + _sensor("broken", "<type>fishbowl</type>")
        + _sensor("bent", "<type>custom</type><custom_function><fun>cos</fun></custom_function>")
    )
    boxes = "".join(_box(name, *box) for name, box in BOXES.items())
    return f"""<?xml version="1.0"?><sdf version="1.9"><world name="wide_boxes">
  <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
  <light type="directional" name="sun"><direction>-0.5 0.1 -0.9</direction></light>
  <model name="rig"><static>true</static><pose>0 0 {HEIGHT_M} 0 0 0</pose>
    <link name="mount">{sensors}</link></model>{boxes}</world></sdf>"""


@pytest.fixture(scope="module", params=["gl", "tiny"])
def sim(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimServer]:
    """The lens and cut-off tests run with each renderer: both draw the cube faces."""
    world = tmp_path_factory.mktemp("wide") / "wide_boxes.sdf"
    world.write_text(world_text())
    with drawn_by(request.param, str(world), BEHIND) as server:
        yield server


def _pixels(msg: object) -> np.ndarray:
    return np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)  # type: ignore[attr-defined]


def _where(image: np.ndarray, rgb: tuple[float, ...]) -> np.ndarray:
    """Pixels of the box of colour `rgb`: its channel well above the others, whatever the shading."""
    channels = image.astype(int)
    main = int(np.argmax(rgb))
    others = [channels[..., i] for i in range(3) if i != main]
    return (channels[..., main] > 90) & (others[0] < 60) & (others[1] < 60)


def _expected(azimuth: float, elevation: float) -> tuple[float, float]:
    """(u, v) where an equidistant lens puts a direction: f·θ from the centre along its azimuth."""
    forward = math.cos(elevation) * math.cos(azimuth)
    right, down = -math.cos(elevation) * math.sin(azimuth), -math.sin(elevation)
    theta = math.acos(forward)
    side = math.hypot(right, down)
    scale = FOCAL * theta / side if side > 0 else 0.0
    return (WIDTH - 1) / 2 + right * scale, (HEIGHT - 1) / 2 + down * scale


def test_boxes_land_where_the_equidistant_lens_puts_their_directions(sim: SimServer) -> None:
    frames = sim.latest({"fisheye": IMAGE, "fisheye/camera_info": CAMERA_INFO}, chunk=100)
    image, info = frames["fisheye"], frames["fisheye/camera_info"]
    assert (image.width, image.height, image.encoding) == (WIDTH, HEIGHT, "rgb8")
    assert image.header.frame_id == "fisheye_optical_frame"
    pixels = _pixels(image)
    for name, (rgb, azimuth, elevation) in BOXES.items():
        mask = _where(pixels, rgb)
        assert mask.sum() > 20, f"the {name} box is not in the image"
        v, u = np.argwhere(mask).mean(axis=0)
        eu, ev = _expected(azimuth, elevation)
        assert abs(u - eu) <= 2.0 and abs(v - ev) <= 2.0, (
            f"{name} at ({u:.1f}, {v:.1f}), lens puts it at ({eu:.1f}, {ev:.1f})"
        )
    assert info.distortion_model == "equidistant" and list(info.d) == [0.0] * 4
    assert info.k[0] == pytest.approx(FOCAL) and info.k[4] == pytest.approx(FOCAL)
    assert (info.k[2], info.k[5]) == ((WIDTH - 1) / 2, (HEIGHT - 1) / 2)


def test_beyond_the_cutoff_angle_the_image_is_black(sim: SimServer) -> None:
    pixels = _pixels(sim.latest({"cut": IMAGE}, chunk=100)["cut"])
    u, v = np.meshgrid(np.arange(WIDTH) - (WIDTH - 1) / 2, np.arange(HEIGHT) - (HEIGHT - 1) / 2)
    radius = np.hypot(u, v)
    cut = FOCAL * 1.0
    assert not pixels[radius > cut + 1.0].any(), "light beyond the cut-off circle"
    inside = pixels[radius < cut - 1.0]
    assert (inside.max(axis=-1) > 0).all(), "black pixels inside the cut-off circle"


@pytest.mark.parametrize(
    ("sensor", "element", "value"), [("broken", "<lens><type>", "fishbowl"), ("bent", "<custom_function><fun>", "cos")]
)
def test_a_lens_that_is_not_gazebos_is_one_line_and_the_world_runs(
    sim: SimServer, sensor: str, element: str, value: str
) -> None:
    lines = [line for line in sim.stderr().splitlines() if f"sensor {sensor}:" in line]
    assert len(lines) == 1 and element in lines[0] and repr(value) in lines[0], lines
    assert "Traceback" not in sim.stderr()
    assert sim.latest({"fisheye": IMAGE}, chunk=100)["fisheye"].width == WIDTH
    assert sim.state()["sim_time"] > 0.0


@pytest.mark.parametrize("kind", sorted(LENS_TYPES))
def test_each_lens_types_radius_is_its_formula(kind: str) -> None:
    theta, f = 0.7, 200.0
    formulas = {
        "gnomonical": f * math.tan(theta),
        "stereographic": 2 * f * math.tan(theta / 2),
        "equidistant": f * theta,
        "equisolid_angle": 2 * f * math.sin(theta / 2),
        "orthographic": f * math.sin(theta),
    }
    c1, c2, c3, lens_f, fun = LENS_TYPES[kind]
    lens = WideLens(kind, c1, c2, c3, lens_f, fun, scale_to_hfov=False)
    assert float(lens.radius(np.float64(theta), f)) == pytest.approx(formulas[kind], rel=1e-12)
    assert float(lens.angle(lens.radius(np.float64(theta), f), f)) == pytest.approx(theta, rel=1e-12)


def test_scale_to_hfov_puts_half_the_field_at_the_image_edge() -> None:
    custom = WideLens("custom", 1.05, 4.0, 0.0, 1.0, "tan")  # gz-sim's wide_angle_camera.sdf
    edge = float(custom.radius(np.float64(3.14 / 2), custom.focal_px(800, 3.14)))
    assert edge == pytest.approx(400.0, rel=1e-9)


def test_camera_info_fits_a_lens_no_ros_model_holds() -> None:
    """Stereographic: OpenCV's fisheye θ_d = θ(1 + k1θ² + …) fitted to 2·tan(θ/2) within 0.1 px."""
    lens = WideLens("stereographic", 2.0, 2.0, 0.0, 1.0, "tan")
    model, fx, d = info_model(lens, WIDTH, HEIGHT, math.pi)
    theta = np.linspace(0.0, 1.2, 50)
    fitted = fx * theta * (1 + sum(k * theta ** (2 * i + 2) for i, k in enumerate(d)))
    assert model == "equidistant" and len(d) == 4
    assert np.abs(fitted - lens.radius(theta, lens.focal_px(WIDTH, math.pi))).max() < 0.1


def test_gz_sims_example_world_publishes_on_its_key(tmp_path: Path) -> None:
    world = gazebo_example("wide_angle_camera.sdf", tmp_path)
    with running_server(
        str(world), "lockstep", cwd=tmp_path, extra=BEHIND, world_name="wide_angle_camera_sensor"
    ) as server:
        frames = server.latest(
            {"wide_angle_camera": IMAGE, "wide_angle_camera/camera_info": CAMERA_INFO}, chunk=34, timeout=180.0
        )
    image, info = frames["wide_angle_camera"], frames["wide_angle_camera/camera_info"]
    assert (image.width, image.height, image.encoding) == (800, 600, "rgb8")
    assert (info.width, info.height) == (800, 600)
    red = _where(_pixels(image), (1.0, 0.0, 0.0))
    assert red.sum() > 100, "the red box (2.2 m away, 63° to the camera's left) is not in the image"
