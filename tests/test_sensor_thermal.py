"""The thermal camera (SDF `thermal` / `thermal_camera`) through the real server: Gazebo's L16 and L8
counts of what the Thermal system and the atmosphere say each pixel sees, mono16 / mono8 with
camera_info; bad parameters are one line each and the world runs.

The test world (written here) has no ground: a rig 1 m up at the origin looks along +x with three
160 × 120 cameras of 90° (fx = 80 px, principal point (79.5, 59.5)), far clip 20 m. Its atmosphere
is 290 K at z = 0, warming 1 K a metre up (steep, so that height shows in counts). Ahead:

- `hot`: a 0.6 m box at (4, 1, 1) whose model has a Thermal of 350 K (near face 3.7 m away, left);
- `marked`: a 0.6 m box at (4, −1, 1) whose visual has a Thermal of 310 K, and a second visual of
  the same link 0.6 m above it with none (the atmosphere's temperature at its height);
- `signed`: a 0.6 m box at (4, 0, −0.4) whose model has a heat signature of 320..300 K (swapped, as
  Gazebo swaps them; not drawn: it shows the hotter bound);
- `wall`: 0.2 × 20 × 4 m, unannotated, near face 7.9 m away, from z 0 to 4; sky above and below.

A pixel (u, v) of a plane square to the axis at depth d sees height z = 1 − (v − 59.5)·d/80. The
sky reads gz-sim's ambient − band/2: band = |1 K/m| × 2·tan(45°)·20 m = 40 K (160 // 120 = 1, so
vfov = hfov), 270 K.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gl_helpers import NO_EGL
from gz_examples import gazebo_example
from server_helpers import SimServer, drawn_by, running_server

from simbot.sim.render import CameraSpec
from simbot.sim.render.thermal_counts import ThermalScale, ThermalSpec, counts8, counts16
from simbot.sim.systems.thermal_camera import ambient_band

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
W, H, FX = 160, 120, 80.0
CX, CY = (W - 1) / 2, (H - 1) / 2
EYE_Z, AMBIENT, GRADIENT, FAR = 1.0, 290.0, 1.0, 20.0
HOT, MARKED, SIGNED = 350.0, 310.0, 320.0
BOX_DEPTH, WALL_DEPTH = 3.7, 7.9
SKY = AMBIENT - 40.0 / 2
NO_ROBOT = ["--robot", "none"]

RANGED = """<plugin name="gz::sim::systems::ThermalSensor" filename="gz-sim-thermal-sensor-system">{}</plugin>"""


def _sensor(name: str, kind: str = "thermal", image_format: str = "L16", plugin: str = "") -> str:
    return f"""<sensor name="{name}" type="{kind}"><update_rate>10</update_rate><topic>{name}</topic>
      <camera><horizontal_fov>{math.pi / 2}</horizontal_fov>
        <image><width>{W}</width><height>{H}</height><format>{image_format}</format></image>
        <clip><near>0.1</near><far>{FAR}</far></clip></camera>{plugin}</sensor>"""


def _box(size: str, extra: str = "") -> str:
    return f"<geometry><box><size>{size}</size></box></geometry>{extra}"


def _thermal(kelvin: float) -> str:
    return f"""<plugin name="gz::sim::systems::Thermal" filename="gz-sim-thermal-system">
      <temperature>{kelvin}</temperature></plugin>"""


def world_text() -> str:
    sensors = (
        _sensor("counts16")
        + _sensor("ranged8", "thermal_camera", "L8", RANGED.format(_range(295, 330, 1.5)))
        + _sensor("default8", image_format="L_INT8")
        + _sensor("bad_format", image_format="R8G8B8")
        + _sensor("bad_range", plugin=RANGED.format(_range(300, 300, 0.1)))
        + _sensor("bad_resolution", plugin=RANGED.format("<resolution>0</resolution>"))
    )
    return f"""<?xml version="1.0"?><sdf version="1.9"><world name="thermal_room">
  <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
  <atmosphere type="adiabatic"><temperature>{AMBIENT}</temperature>
    <temperature_gradient>{GRADIENT}</temperature_gradient></atmosphere>
  <light type="directional" name="sun"><direction>-0.5 0.1 -0.9</direction></light>
  <model name="rig"><static>true</static><pose>0 0 {EYE_Z} 0 0 0</pose><link name="mount">{sensors}</link></model>
  <model name="hot"><static>true</static><pose>4 1 1 0 0 0</pose>
    <link name="link"><visual name="v">{_box("0.6 0.6 0.6")}</visual></link>{_thermal(HOT)}</model>
  <model name="marked"><static>true</static><pose>4 -1 1 0 0 0</pose><link name="link">
    <visual name="warm">{_box("0.6 0.6 0.6", _thermal(MARKED))}</visual>
    <visual name="plain"><pose>0 0 0.6 0 0 0</pose>{_box("0.6 0.6 0.6")}</visual></link></model>
  <model name="signed"><static>true</static><pose>4 0 -0.4 0 0 0</pose>
    <link name="link"><visual name="v">{_box("0.6 0.6 0.6")}</visual></link>
    <plugin name="gz::sim::systems::Thermal" filename="gz-sim-thermal-system">
      <heat_signature>signature.png</heat_signature><min_temp>{SIGNED}</min_temp><max_temp>300</max_temp></plugin></model>
  <model name="wall"><static>true</static><pose>8 0 2 0 0 0</pose>
    <link name="link"><visual name="v">{_box("0.2 20 4")}</visual></link></model>
</world></sdf>"""


def _range(low: float, high: float, resolution: float) -> str:
    return f"<min_temp>{low}</min_temp><max_temp>{high}</max_temp><resolution>{resolution}</resolution>"


@pytest.fixture(scope="module", params=["gl", "tiny"])
def sim(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimServer]:
    """Every test runs with each renderer: TinyRenderer gives unannotated geometry the atmosphere at z = 0."""
    world = tmp_path_factory.mktemp("thermal") / "thermal_room.sdf"
    world.write_text(world_text())
    with drawn_by(request.param, str(world), NO_ROBOT) as server:
        server.renderer = request.param  # type: ignore[attr-defined]  # which renderer the tests expect
        yield server


def renderer_of(sim: SimServer) -> str:
    """The renderer the module's fixture started `sim` with."""
    renderer: str = sim.renderer  # type: ignore[attr-defined]
    return renderer


def counts(msg: Any) -> np.ndarray:
    """The image's counts: uint16 of a mono16 image (little-endian), uint8 of a mono8 one."""
    dtype = np.dtype({"mono16": "<u2", "mono8": "u1"}[msg.encoding])
    return np.frombuffer(bytes(msg.data), dtype=dtype).reshape(msg.height, msg.width)


def pixel(y: float, z: float, depth: float) -> tuple[int, int]:
    """(row, column) of the pixel nearest to a point `y` left of the axis and at height `z`, `depth` ahead."""
    return round(CY - FX * (z - EYE_Z) / depth), round(CX - FX * y / depth)


def height_at(row: int, depth: float) -> float:
    """The height a pixel centre of `row` sees on a plane square to the axis `depth` ahead."""
    return EYE_Z - (row - CY) * depth / FX


def air(sim: SimServer, z: float) -> float:
    """What unannotated geometry at height z reads (K): the atmosphere there; TinyRenderer's at z = 0."""
    return AMBIENT + GRADIENT * (z if renderer_of(sim) == "gl" else 0.0)


def patch(image: np.ndarray, row: int, column: int) -> np.ndarray:
    return image[row - 2 : row + 3, column - 2 : column + 3]


def frames(sim: SimServer, *names: str) -> dict[str, Any]:
    return sim.latest({name: IMAGE for name in names}, chunk=100, timeout=120.0)


def test_l16_reads_each_thermal_temperature_in_hundredths_of_a_kelvin(sim: SimServer) -> None:
    shown = frames(sim, "counts16")["counts16"]
    assert (shown.width, shown.height, shown.encoding, shown.step, shown.is_bigendian) == (W, H, "mono16", 2 * W, 0)
    assert shown.header.frame_id == "counts16_optical_frame"
    image = counts(shown)
    assert (patch(image, *pixel(1.0, 1.0, BOX_DEPTH)) == round(HOT * 100)).all(), "the hot box (Thermal on its model)"
    warm = patch(image, *pixel(-1.0, 1.0, BOX_DEPTH))
    assert (warm == round(MARKED * 100)).all(), "the marked box (Thermal on its visual)"


def test_a_heat_signature_shows_its_hotter_bound_with_a_warning(sim: SimServer) -> None:
    image = counts(frames(sim, "counts16")["counts16"])
    assert (patch(image, *pixel(0.0, -0.4, BOX_DEPTH)) == round(SIGNED * 100)).all()
    warned = [line for line in sim.stderr().splitlines() if "<heat_signature> is not drawn" in line]
    assert len(warned) == 1 and "signed" in warned[0], warned


def test_unannotated_geometry_reads_the_atmosphere_at_its_height(sim: SimServer) -> None:
    """The wall at two heights, and the marked box's second visual, which its sibling's Thermal does
    not cover (TinyRenderer tells a link's visuals apart by link only: GL alone for that one)."""
    image = counts(frames(sim, "counts16")["counts16"])
    for z in (0.5, 3.5):
        row, column = pixel(0.0, z, WALL_DEPTH)
        expected = air(sim, height_at(row, WALL_DEPTH)) * 100
        assert abs(int(image[row, column]) - expected) <= 1, f"the wall at {z} m reads {image[row, column]}"
    assert abs(int(image[pixel(0.0, 0.5, WALL_DEPTH)]) - int(image[pixel(0.0, 3.5, WALL_DEPTH)])) == (
        pytest.approx(GRADIENT * 3.0 * 100, abs=6) if renderer_of(sim) == "gl" else 0
    )
    if renderer_of(sim) == "gl":
        row, column = pixel(-1.0, 1.6, BOX_DEPTH)
        assert abs(int(image[row, column]) - air(sim, height_at(row, BOX_DEPTH)) * 100) <= 1


def test_the_sky_reads_gazebos_bottom_of_the_ambient_band(sim: SimServer) -> None:
    image = counts(frames(sim, "counts16")["counts16"])
    assert ambient_band(GRADIENT, math.pi / 2, W, H, FAR) == pytest.approx(40.0)
    assert (image[:3] == round(SKY * 100)).all() and (image[-3:] == round(SKY * 100)).all()


def test_l8_counts_its_range_at_its_resolution(sim: SimServer) -> None:
    """`ranged8` (295..330 K, 1.5 K a count): the hot box clamps to 330 K, the wall and the sky to 295 K.
    `default8` (Gazebo's 3 K a count, unbounded): each temperature over 3."""
    shown = frames(sim, "ranged8", "default8")
    ranged, default = counts(shown["ranged8"]), counts(shown["default8"])
    assert shown["ranged8"].encoding == shown["default8"].encoding == "mono8" and shown["ranged8"].step == W
    hot, marked, wall = pixel(1.0, 1.0, BOX_DEPTH), pixel(-1.0, 1.0, BOX_DEPTH), pixel(0.0, 2.0, WALL_DEPTH)
    assert (ranged[hot], ranged[marked], ranged[wall], ranged[0, 0]) == (220, 207, 197, 197)
    assert (default[hot], default[marked], default[0, 0]) == (117, 103, 90)
    assert default[wall] == round(air(sim, height_at(wall[0], WALL_DEPTH)) / 3.0)


def test_camera_info_pairs_each_image_with_its_intrinsics(sim: SimServer) -> None:
    topics = {"counts16": IMAGE, "counts16/camera_info": CAMERA_INFO}
    collectors = {topic: sim.subscribe(topic, kind) for topic, kind in topics.items()}
    sim.prime(*collectors.values(), chunk=100, timeout=120.0)
    stamps = {
        topic: {(m.header.stamp.sec, m.header.stamp.nanosec) for m in c.messages()} for topic, c in collectors.items()
    }
    sim.unsubscribe_all()
    assert stamps["counts16"] <= stamps["counts16/camera_info"], "an image without its camera_info"
    info = collectors["counts16/camera_info"].messages()[-1]
    assert (info.width, info.height, info.distortion_model) == (W, H, "plumb_bob")
    assert np.allclose(info.k, [FX, 0, CX, 0, FX, CY, 0, 0, 1]) and not np.any(info.d)


def test_bad_parameters_are_one_line_each_and_the_world_runs(sim: SimServer) -> None:
    for name, element in (("bad_format", "<format>"), ("bad_range", "<min_temp>"), ("bad_resolution", "<resolution>")):
        lines = [line for line in sim.stderr().splitlines() if f"sensor {name}:" in line]
        assert len(lines) == 1 and element in lines[0], lines
        assert f"rig/mount/{name}" not in sim.state()["sensors"]
    assert "Traceback" not in sim.stderr()
    assert frames(sim, "counts16")["counts16"].width == W


def test_counts_saturate_as_gazebos_unorm_target_does() -> None:
    """Above 655.35 K at 0.01 K a count, L16 holds 65535 (and L8 255 above 765 K at 3 K); below
    min_temp a reading is min_temp's count; nothing drawn reads the background."""
    spec = ThermalSpec("c", 4, 1, 1.0, 0.1, 10.0, outputs=("thermal16", "thermal8"))
    kelvin = np.array([[700.0, 800.0, 0.0, 100.0]], dtype=np.float32)
    sixteen, eight = np.empty((1, 4), np.uint16), np.empty((1, 4), np.uint8)
    counts16(spec)(sixteen, {"temperature": kelvin})
    counts8(CameraSpec("plain", 4, 1, 1.0, 0.1, 10.0, outputs=("thermal8",)))(eight, {"temperature": kelvin})
    assert sixteen.tolist() == [[65535, 65535, 28815, 10000]]
    assert eight.tolist() == [[233, 255, 96, 33]]
    ranged = ThermalSpec.of(spec, ThermalScale(0.5, min_temp=200.0, max_temp=750.0, background=250.0))
    counts16(ranged)(sixteen, {"temperature": kelvin})
    assert sixteen.tolist() == [[1400, 1500, 500, 400]]


def test_gz_sims_example_world_publishes_on_its_keys(tmp_path: Path) -> None:
    """thermal_camera.sdf: 300 K air warming 0.1 K/m; its red box 285 K (a visual's Thermal), its
    near face 5.05 m ahead of the cameras (they face −x), 0.95 m to their right and 0.05 m below;
    the sky 300 − band/2 with gz-sim's band 0.1 × 2·tan(1.047/2) × 100 m = 11.55 K."""
    if NO_EGL:
        pytest.skip(NO_EGL)
    world = gazebo_example("thermal_camera.sdf", tmp_path)
    keys = {"thermal_camera": IMAGE, "thermal_camera/camera_info": CAMERA_INFO}
    keys |= {"thermal_camera_8bit/image": IMAGE, "thermal_camera_8bit/camera_info": CAMERA_INFO}
    with running_server(str(world), "lockstep", cwd=tmp_path, extra=NO_ROBOT) as server:
        shown = server.latest(keys, chunk=34, timeout=180.0)
    sixteen, eight = shown["thermal_camera"], shown["thermal_camera_8bit/image"]
    assert (sixteen.width, sixteen.height, sixteen.encoding, eight.encoding) == (320, 240, "mono16", "mono8")
    fx = 160 / math.tan(1.047 / 2)
    row, column = round(119.5 + fx * 0.05 / 5.05), round(159.5 + fx * 0.95 / 5.05)
    assert counts(sixteen)[row, column] == 28500 and counts(eight)[row, column] == 95
    sky = 300.0 - ambient_band(0.1, 1.047, 320, 240, 100.0) / 2
    assert counts(sixteen)[0, 0] == round(sky * 100) and counts(eight)[0, 0] == round(sky / 3.0)
