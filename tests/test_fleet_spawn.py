"""A fleet made at run time: world control's create and remove, each tug in a namespace (issue 17, items 1 and 2).

One lockstep server of the empty world and no robot (`--robot none`); the tests create tugs
`tug_1..tug_9` in namespaces of their names, 2 m apart along y, and a "mast" of their own (a
0.5 m cube on the floor, above the tug's lidar plane at 0.26 m, which the tug's own chassis top
at 0.205 m is not) 3 m ahead of tug_5's front lidar.

Figures: 0.5 m/s for 3 s is 1.5 m; the diff drive's wheels slip a little at the start and the
motor ramps in a few steps: ±0.2 m. A tug nobody drives rests on its wheels after settling:
its planar position changes less than 1 cm. The front lidar sits 0.99 m ahead of the tug's
origin; its two middle rays (±half an increment off the axis, cos ≈ 1 − 2e-6) meet the mast's
face 3.00 m ahead, quantised to 0.01 m: ±0.006 m, plus the tug's settling (well under 1 mm).

Cameras while the world changes (the last tests): a lockstep server with the robot, its front
camera watched, so the render workers run when a red box and a tug are created: the box appears
in the robot's image with its pinhole size and goes when removed; the tug's own camera publishes
at its rate; the images across a create are the same, byte for byte, run to run.
"""

from __future__ import annotations

import json
import math
import subprocess
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from conftest import REPO
from server_helpers import (
    Collector,
    SimServer,
    keyed_payload,
    planar_distance,
    raw_samples,
    render_workers,
    running_server,
    server_command,
    stamp_ns,
    wait_until,
)

from simbot import memory
from simbot.bus import messages
from simbot.bus.graph import discover
from simbot.description.fleet import TUG_BYTES, WORLD_BYTES
from simbot.description.model import Scene
from simbot.sim import server
from simbot.transform import quaternion_to_matrix

SCAN = "sensor_msgs/msg/LaserScan"
TUGS = 9
SPACING = 2.0
DRIVEN = "tug_5"
TUG_SDF = REPO / "urdf" / "flexley_tug.sdf"
CHEAP_CAMERAS = ("--robot", "none", "--camera-size", "8x6", "--camera-rate", "1")
SETTLE_STEPS = 500
STOP_STEPS = 1500
"""Steps for a stop command to arrive and the tug to come to rest (its DiffDrive states no acceleration
limit: the wheels' velocity servos stop it within a fraction of a second)."""
LIDAR_X, MAST_GAP, MAST_HALF = 0.99, 3.0, 0.25
RANGE_TOLERANCE = 0.006

MAST = f"""<?xml version="1.0"?>
<sdf version="1.9">
  <model name="mast">
    <link name="body">
      <inertial><mass>10</mass><inertia><ixx>0.42</ixx><iyy>0.42</iyy><izz>0.42</izz></inertia></inertial>
      <collision name="collision"><geometry><box><size>{2 * MAST_HALF} {2 * MAST_HALF} {2 * MAST_HALF}</size></box></geometry></collision>
    </link>
  </model>
</sdf>"""


def _pose(x: float, y: float, z: float = 0.1) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": {"w": 1.0}}


def _tug_y(index: int) -> float:
    return (index - 1) * SPACING


def create_tug(sim: SimServer, index: int) -> dict[str, Any]:
    name = f"tug_{index}"
    request = {"sdf_filename": str(TUG_SDF), "name": name, "namespace": name, "pose": _pose(0.0, _tug_y(index))}
    return sim.call("create", request, timeout=60.0)


@pytest.fixture(scope="module", name="fleet")
def fleet_server() -> Iterator[SimServer]:
    """Nine tugs created at run time, settled on their wheels."""
    with running_server("empty", extra=CHEAP_CAMERAS) as sim:
        for index in range(1, TUGS + 1):
            assert create_tug(sim, index) == {"ok": True, "name": f"tug_{index}"}
        sim.step(SETTLE_STEPS)
        yield sim


def _planar(sim: SimServer, state: dict[str, Any]) -> dict[str, tuple[float, float, float]]:
    return {name: sim.pose(name, state)[0] for name in state["models"] if name.startswith("tug_")}


def test_one_tug_driven_on_its_namespace_moves_and_the_others_stay(fleet: SimServer) -> None:
    """tug_5/cmd_vel at 0.5 m/s for 3 s: tug_5 moves 1.5 m ± 0.2, every other tug less than 1 cm."""
    before = _planar(fleet, fleet.state())
    assert len(before) == TUGS
    fleet.send(f"{DRIVEN}/cmd_vel", messages.twist((0.5, 0.0, 0.0), (0.0, 0.0, 0.0)))
    fleet.step(3000)
    fleet.send(f"{DRIVEN}/cmd_vel", messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    fleet.step(1)
    after = _planar(fleet, fleet.state())
    moved = {name: planar_distance(before[name], after[name]) for name in before}
    print(f"\nmoved: {', '.join(f'{name} {d:.4f} m' for name, d in sorted(moved.items()))}")
    assert moved.pop(DRIVEN) == pytest.approx(1.5, abs=0.2)
    assert max(moved.values()) < 0.01


def test_namespaced_keys_and_frames(fleet: SimServer) -> None:
    """tug_5's odometry on tug_5/odom in frames tug_5/odom → tug_5/base_footprint; its ground truth on model/tug_5/pose."""
    latest = fleet.latest(
        {
            f"{DRIVEN}/odom": "nav_msgs/msg/Odometry",
            f"model/{DRIVEN}/pose": "geometry_msgs/msg/PoseStamped",
        }
    )
    tf_static = fleet.subscribe(f"{DRIVEN}/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
    (static,) = tf_static.wait_count(1, what="the latched tf_static")
    odom = latest[f"{DRIVEN}/odom"]
    assert (odom.header.frame_id, odom.child_frame_id) == (f"{DRIVEN}/odom", f"{DRIVEN}/base_footprint")
    assert latest[f"model/{DRIVEN}/pose"].header.frame_id == "world"
    frames = {(t.header.frame_id, t.child_frame_id) for t in static.transforms}
    assert (f"{DRIVEN}/base_link", f"{DRIVEN}/base_scan_front") in frames
    assert all(parent.startswith(f"{DRIVEN}/") and child.startswith(f"{DRIVEN}/") for parent, child in frames)


def test_each_tug_s_odometry_frame_hangs_from_world_where_it_entered(fleet: SimServer) -> None:
    """The scene's tf places world → tug_k/odom (viewers draw scans over the walls), at the tug's
    entry: x 0, y its spacing (±5 cm: it settles on its wheels); no tug claims a bare `odom`."""
    transforms = fleet.subscribe("tf", "tf2_msgs/msg/TFMessage")
    fleet.step(200)  # the scene's frames go out at 10 Hz

    def placed(msgs: list[Any]) -> dict[str, Any]:
        return {
            t.child_frame_id: t.transform.translation
            for m in msgs
            for t in m.transforms
            if t.header.frame_id == "world"
        }

    found = transforms.wait_for(lambda msgs: f"{DRIVEN}/odom" in placed(msgs), timeout=30.0, what="world → tug_5/odom")
    where = placed(found)
    assert where[f"{DRIVEN}/odom"].x == pytest.approx(0.0, abs=0.05)
    assert where[f"{DRIVEN}/odom"].y == pytest.approx(_tug_y(5), abs=0.05)
    assert "odom" not in where


def test_lidar_sees_a_robot_placed_ahead(fleet: SimServer) -> None:
    """tug_5's front lidar: 720 rays, the mast's face 3.00 m ahead on the middle rays."""
    fleet.send(f"{DRIVEN}/cmd_vel", messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    fleet.step(STOP_STEPS)  # at rest, whatever another test left it doing: the mast is placed from its pose
    (x, y, _), _ = fleet.pose(DRIVEN)
    mast_x = x + LIDAR_X + MAST_GAP + MAST_HALF
    reply = fleet.call("create", {"sdf": MAST, "name": "mast", "pose": _pose(mast_x, y, MAST_HALF)})
    assert reply == {"ok": True, "name": "mast"}
    try:
        scan = fleet.latest({f"{DRIVEN}/lidar_front": SCAN})[f"{DRIVEN}/lidar_front"]
        ranges = np.asarray(scan.ranges, dtype=float)
        assert ranges.size == 720
        middle = ranges[359:361]
        print(f"\nthe mast at {middle} m (expected {MAST_GAP})")
        assert middle == pytest.approx([MAST_GAP, MAST_GAP], abs=RANGE_TOLERANCE)
        assert scan.header.frame_id == f"{DRIVEN}/base_scan_front"
    finally:
        assert fleet.call("remove", {"name": "mast"})["ok"] is True


@pytest.mark.parametrize(
    ("request_body", "field"),
    [
        ({"sdf_filename": "/nonexistent/tug.sdf", "name": "x"}, "sdf_filename"),
        ({"sdf": "<sdf version='1.9'><model name='m'><link name='l'>", "name": "x"}, "sdf"),
        ({"sdf_filename": str(TUG_SDF), "name": "tug_1"}, "name"),
        ({"sdf_filename": str(TUG_SDF), "name": "x", "pose": {"position": {"x": math.nan}}}, "pose.position.x"),
        ({"sdf_filename": str(TUG_SDF), "name": "x", "pose": {"position": {"y": math.inf}}}, "pose.position.y"),
        ({"sdf_filename": str(TUG_SDF), "name": "x", "namespace": "bad ns*"}, "namespace"),
        ({"sdf_filename": str(TUG_SDF), "sdf": MAST}, "sdf_filename or sdf"),
        ({"sdf": MAST, "name": "a/b"}, "name"),
    ],
    ids=[
        "missing file",
        "malformed sdf",
        "duplicate name",
        "nan pose",
        "infinite pose",
        "bad namespace",
        "both",
        "bad name",
    ],
)
def test_bad_create_changes_nothing(fleet: SimServer, request_body: dict[str, Any], field: str) -> None:
    """One line naming the field; the same models and the same keys on the graph after as before."""
    models = set(fleet.state()["models"])
    keys = discover(fleet.node.session, fleet.namespace)
    reply = fleet.node.call(f"world/{fleet.world}/create", json.dumps(request_body).encode(), timeout=30.0)
    assert reply["ok"] is False
    assert reply["error"].startswith(field) and "\n" not in reply["error"], reply
    assert set(fleet.state()["models"]) == models
    assert discover(fleet.node.session, fleet.namespace) == keys


def test_a_tug_created_on_another_is_refused_naming_both_and_beside_it_is_made(fleet: SimServer) -> None:
    """A create whose tug would stand on ground tug_5 takes up (0.3 m off it, its 2.1 × 0.5 m
    chassis and wheels overlapping) is answered with an error naming both, and nothing is made;
    one a metre beside tug_5 (half the spacing; the outline is the chassis, 2.1 × 0.5 m) is made, then removed."""
    x, y, _ = fleet.pose("tug_5")[0]
    request = {"sdf_filename": str(TUG_SDF), "name": "tug_over", "namespace": "tug_over", "pose": _pose(x + 0.3, y)}
    reply = fleet.call("create", request, timeout=60.0)
    assert reply["ok"] is False and "tug_over" in reply["error"] and "tug_5" in reply["error"], reply
    assert "tug_over" not in fleet.state()["models"]
    request["pose"] = _pose(x, y + SPACING / 2)
    assert fleet.call("create", request, timeout=60.0) == {"ok": True, "name": "tug_over"}
    assert fleet.call("remove", {"name": "tug_over"}) == {"ok": True, "name": "tug_over"}


def test_duplicate_name_renamed_when_allowed_and_unknown_remove(fleet: SimServer) -> None:
    """allow_renaming gives mast_1 beside mast; remove of a name not in the world: ok false naming the field."""
    first = fleet.call("create", {"sdf": MAST, "name": "mast", "pose": _pose(-5.0, 0.0, MAST_HALF)})
    second = fleet.call(
        "create", {"sdf": MAST, "name": "mast", "allow_renaming": True, "pose": _pose(-7.0, 0.0, MAST_HALF)}
    )
    assert (first["name"], second["name"]) == ("mast", "mast_1")
    for name in ("mast", "mast_1"):
        assert fleet.call("remove", {"name": name}) == {"ok": True, "name": name}
    reply = fleet.call("remove", {"name": "mast"})
    assert reply["ok"] is False and reply["error"].startswith("name")


def _graph_tokens(fleet: SimServer) -> list[list[str]]:
    """Every rmw_zenoh liveliness token on the bus, split into its chunks."""
    replies = fleet.node.session.liveliness().get("@ros2_lv/0/**", timeout=2.0)
    return [str(reply.ok.key_expr).split("/") for reply in replies if reply.ok is not None]


def _robot_node(fleet: SimServer, robot: str) -> tuple[str, list[str]] | None:
    """(the node id, the topics it announces) of the node `robot` runs on the graph, or None."""
    tokens = _graph_tokens(fleet)
    scope = f"%{fleet.namespace}%{robot}"
    nodes = [chunks[3] for chunks in tokens if chunks[5] == "NN" and chunks[7] == scope and chunks[8] == "simbot"]
    if not nodes:
        return None
    return nodes[0], [chunks[9] for chunks in tokens if chunks[3] == nodes[0] and chunks[5] != "NN"]


def test_remove_takes_its_keys_off_the_graph(fleet: SimServer) -> None:
    """tug_9 removed: no key under tug_9/ nor its model/tug_9/pose is left, nor its node on the
    graph (each tug is a node of its own, `/<ns>/tug_9/simbot`, announcing its topics); tug_8's
    keys and node are all there."""

    def under(prefix: str) -> set[str]:
        return {e.key for e in discover(fleet.node.session, fleet.namespace) if f"/{prefix}/" in f"/{e.key}"}

    assert f"{fleet.namespace}/tug_9/cmd_vel" in under("tug_9")
    node = _robot_node(fleet, "tug_9")
    assert node is not None and f"%{fleet.namespace}%tug_9%cmd_vel" in node[1], node
    tug_8 = under("tug_8")
    assert fleet.call("remove", {"name": "tug_9"}) == {"ok": True, "name": "tug_9"}
    assert under("tug_9") == set()
    assert _robot_node(fleet, "tug_9") is None
    assert under("tug_8") == tug_8
    assert _robot_node(fleet, "tug_8") is not None
    assert "tug_9" not in fleet.state()["models"]
    fleet.step(10)


def _run_with_a_create(seed: int) -> dict[str, list[bytes]]:
    """Every message of a lockstep run that creates a tug after 100 steps and drives it for 400: by key, in order."""
    with running_server("empty", seed=seed, extra=CHEAP_CAMERAS) as sim:
        prefix = len(sim.namespace) + 1
        with raw_samples(sim.node.session, f"0/{sim.namespace}/**", keyed_payload) as received:
            sim.step(100)
            assert create_tug(sim, 2)["ok"] is True
            sim.send("tug_2/cmd_vel", messages.twist((0.3, 0.0, 0.0), (0.0, 0.0, 0.2)))
            sim.step(400)
            sim.step(1)
            wait = sim.state()["iterations"]
            assert wait == 501
            published: dict[str, list[bytes]] = {}
            for key, data in received.messages():
                published.setdefault(key[prefix:], []).append(data)
    return published


def test_lockstep_is_deterministic_across_a_create() -> None:
    """Two runs with one seed and the same calls publish byte-identical messages on every key."""
    first, second = _run_with_a_create(7), _run_with_a_create(7)
    assert {"tug_2/odom", "tug_2/lidar_front", "tug_2/imu_scan", "clock"} <= set(first)
    assert set(first) == set(second)
    for key in first:
        assert first[key] == second[key], key


TROLLEY_SDF = REPO / "worlds" / "models" / "trolley" / "model.sdf"
IMAGE = "sensor_msgs/msg/Image"


def test_remove_while_attached_frees_the_trolley_and_while_rendering_ends_the_workers() -> None:
    """A tug pulling the trolley with its front camera rendering, removed: its joint state says
    detached, its render workers end (its cameras were the last); a tug created after that starts
    them again for its camera; a reset removes the trolley and that tug, created at run time too."""
    with running_server("empty", extra=CHEAP_CAMERAS) as sim:
        assert sim.call("create", {"sdf_filename": str(TROLLEY_SDF), "name": "trolley", "pose": _pose(1.0, 0.2, 0.0)})[
            "ok"
        ]
        assert create_tug(sim, 1)["ok"]
        state = sim.subscribe("tug_1/detachable_joint/state", "std_msgs/msg/String", latched=True)
        sim.send("tug_1/attach", messages.empty())
        sim.step(10)
        state.wait_for(lambda msgs: msgs and msgs[-1].data == "attached", what="attached")
        images = sim.subscribe("tug_1/camera_front", IMAGE)
        sim.prime(images, chunk=1000, timeout=60.0)
        assert render_workers(sim.process.pid), "no render worker while tug_1/camera_front renders"
        assert sim.call("remove", {"name": "tug_1"}) == {"ok": True, "name": "tug_1"}
        state.wait_for(lambda msgs: msgs[-1].data == "detached", what="detached on removal")
        wait_until(lambda: not render_workers(sim.process.pid), 10.0, "the render workers to end")
        sim.step(100)
        assert set(sim.state()["models"]) == {"ground_plane", "trolley"}
        assert create_tug(sim, 2)["ok"]
        sim.prime(sim.subscribe("tug_2/camera_front", IMAGE), chunk=1000, timeout=60.0)
        assert render_workers(sim.process.pid), "no render worker while tug_2/camera_front renders"
        sim.unsubscribe_all()
        assert sim.control({"reset": {"all": True}})["ok"] is True
        assert set(sim.state()["models"]) == {"ground_plane"}, "a reset keeps no model created at run time"


def test_robots_n_starts_tugs_in_a_row_each_in_its_namespace() -> None:
    """--robots 3: tug_1..tug_3 from --spawn along y, 1.5 m apart, each taking commands on its own cmd_vel;
    one removed, a reset says it cannot bring it back, and the world runs on."""
    extra = ("--robots", "3", "--spawn", "1", "2", "0.1", "0", "--camera-size", "8x6", "--camera-rate", "1")
    with running_server("empty", extra=extra) as sim:
        state = sim.state()
        assert {"tug_1", "tug_2", "tug_3"} <= set(state["models"]) and "flexley_tug" not in state["models"]
        for index in (1, 2, 3):
            (x, y, _), _ = sim.pose(f"tug_{index}", state)
            assert (x, y) == pytest.approx((1.0, 2.0 + (index - 1) * 1.5), abs=1e-6)
            assert sim.key(f"tug_{index}/cmd_vel") in state["received"]
        assert sim.call("remove", {"name": "tug_3"})["ok"] is True
        reply = sim.control({"reset": {"all": True}})
        assert reply["ok"] is False and "tug_3" in reply["error"], "a model the world started with cannot come back"
        sim.step(10)


def test_robots_without_a_robot_is_a_usage_error() -> None:
    result = subprocess.run(
        server_command("--robots", "2", "--robot", "none"), capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2 and "--robots" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("count", ["0", "-3"])
def test_robots_zero_or_negative_is_one_line_naming_the_option(count: str) -> None:
    result = subprocess.run(server_command("--robots", count), capture_output=True, text=True, timeout=60)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and "--robots" in lines[-1] and "Traceback" not in result.stderr, result.stderr


def test_robots_past_what_memory_allows_is_one_line_and_nothing_starts(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A thousand tugs need about 3 GiB (TUG_BYTES each, measured); with 1 GiB available the server
    says so in one line, how many would fit, and exits 2 before it opens a bus or loads a model."""
    monkeypatch.setattr(memory, "available", lambda: 8 << 30)
    assert memory.shortfall("--robots", 1000, TUG_BYTES, WORLD_BYTES, "a tug") is None
    monkeypatch.setattr(memory, "available", lambda: 1 << 30)
    code = server.main(["--world", "empty", "--robots", "1000", "--physics", "kinematic", "--mode", "lockstep"])
    err = capsys.readouterr().err.strip().splitlines()
    fits = ((1 << 30) - WORLD_BYTES) // TUG_BYTES
    assert code == 2 and len(err) == 1 and "--robots 1000" in err[0] and f"{fits} fit" in err[0], err


# --- cameras while the world changes: a robot's front camera watched, then a tug and a box created

SIZE, RATE, HFOV = (160, 120), 10.0, 2.0944
"""Every camera's image and rate (--camera-size, --camera-rate); the tug's horizontal field of view."""
FX = SIZE[0] / 2 / math.tan(HFOV / 2)
FRONT_CAMERA = (1.0, 0.0, 0.48)
"""The front camera in the tug's model frame: (1.0, 0, 0.39) on base_link, 0.09 above base_footprint."""
BOX_GAP, BOX_HALF = 1.5, 0.25
FRAME_NS = round(1e9 / RATE)
WATCHED = ("--camera-size", f"{SIZE[0]}x{SIZE[1]}", "--camera-rate", str(RATE))


RED_BOX = f"""<?xml version="1.0"?>
<sdf version="1.9">
  <model name="box"><static>true</static>
    <link name="body">
      <visual name="visual"><geometry><box><size>{2 * BOX_HALF} {2 * BOX_HALF} {2 * BOX_HALF}</size></box></geometry>
        <material><ambient>1 0 0 1</ambient><diffuse>1 0 0 1</diffuse></material></visual>
    </link>
  </model>
</sdf>"""
"""A red cube, static so that it stays where it is put: in the air, on a camera's axis."""


@pytest.fixture(scope="module", name="watched")
def watched_server() -> Iterator[SimServer]:
    """The robot in the empty world, lockstep, its front camera watched until it published: the render
    workers run from then on, for the server's life."""
    with running_server("empty", extra=WATCHED) as sim:
        _watch_front_camera(sim)
        yield sim


def _watch_front_camera(sim: SimServer) -> Collector[Any]:
    """The robot settled, its front camera's images coming (the render workers run)."""
    sim.step(SETTLE_STEPS)
    images = sim.subscribe("camera_front", IMAGE)
    sim.prime(images, chunk=100, timeout=60.0)
    assert render_workers(sim.process.pid)
    return images


def _camera_and_axis(sim: SimServer) -> tuple[np.ndarray, np.ndarray]:
    """The robot's front camera in the world and its optical axis, from the model's true pose."""
    position, quat = sim.pose()
    rotation = quaternion_to_matrix(quat)
    return np.asarray(position) + rotation @ FRONT_CAMERA, rotation[:, 0]


def _frames_after(sim: SimServer, images: Collector[Any], after_ns: int) -> list[Any]:
    """Steps a frame's time at a time until a frame taken after `after_ns` is out; the frames since."""
    sim.step(FRAME_NS // 1_000_000)
    return images.wait_for(lambda msgs: any(stamp_ns(m) > after_ns for m in msgs), what="a new frame")


def _red(msg: Any) -> npt.NDArray[np.bool_]:
    """The pixels of the red box (lit by ambient light only, its face away from the sun: 0.6 of red)."""
    pixels = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width, 3).astype(int)
    return (pixels[..., 0] > 100) & (pixels[..., 1] < 40) & (pixels[..., 2] < 40)


def test_a_box_created_before_a_running_camera_appears_in_its_image(watched: SimServer) -> None:
    """A 0.5 m red cube created 1.5 m ahead of the watched camera, square to its axis: fx·0.5/1.5 = 15.4 px
    wide and high (±1 px: which pixel centres the edges cover), centred on the principal point (±1 px); removed,
    it is gone from the next frame."""
    camera, axis = _camera_and_axis(watched)
    centre = camera + axis * (BOX_GAP + BOX_HALF)
    _, quat = watched.pose()
    pose = {"position": dict(zip("xyz", centre.tolist())), "orientation": dict(zip("xyzw", quat))}
    images = watched.subscribe("camera_front", IMAGE)
    try:
        created = watched.step(0)["sim_time"]
        assert watched.call("create", {"sdf": RED_BOX, "name": "box", "pose": pose})["ok"] is True
        frame = _frames_after(watched, images, round(created * 1e9))[-1]
        red = _red(frame)
        assert red.any(), "the box is not in the image"
        rows, columns = np.nonzero(red)
        expected = FX * 2 * BOX_HALF / BOX_GAP
        print(f"\nthe box: {np.ptp(columns) + 1} x {np.ptp(rows) + 1} px (expected {expected:.1f})")
        assert np.ptp(columns) + 1 == pytest.approx(expected, abs=1)
        assert np.ptp(rows) + 1 == pytest.approx(expected, abs=1)
        assert (columns.mean(), rows.mean()) == pytest.approx(((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2), abs=1)
        removed = stamp_ns(frame)
        assert watched.call("remove", {"name": "box"})["ok"] is True
        assert not _red(_frames_after(watched, images, removed)[-1]).any()
    finally:
        watched.unsubscribe_all()


def test_a_tug_created_while_cameras_render_publishes_its_camera_at_its_rate(watched: SimServer) -> None:
    """tug_2 created beside the robot: its front camera publishes every 0.1 s of sim time, 10 frames over
    1000 steps stamped with the sim time of each tick, each a picture of the floor below the sky."""
    (x, y, _), _ = watched.pose()
    assert create_tug(watched, 2) == {"ok": True, "name": "tug_2"}
    try:
        images = watched.subscribe("tug_2/camera_front", IMAGE)
        watched.prime(images, chunk=100, timeout=30.0)
        start = round(watched.step(0)["sim_time"] * 1e9)
        images.clear()
        watched.step(1000)
        frames = images.wait_count(10, what="tug_2's frames over 1 s")
        stamps = [stamp_ns(m) for m in frames]
        assert stamps == [start + FRAME_NS * (k + 1) for k in range(10)]  # every step count here is whole frames
        pixels = np.frombuffer(frames[-1].data, dtype=np.uint8).reshape(SIZE[1], SIZE[0], 3)
        sky = np.rint(np.asarray(Scene().background[:3]) * 255)  # the empty world has no <scene>: SDF's default
        assert np.abs(pixels[0] - sky).max() <= 1, "the sky is not the world's background"
        assert (np.abs(pixels[-1] - sky).max(axis=-1) > 1).all(), "the floor is not drawn"
    finally:
        watched.unsubscribe_all()
        assert watched.call("remove", {"name": "tug_2"})["ok"] is True


def _frames_across_a_create(seed: int) -> dict[int, bytes]:
    """The front camera's images, by stamp: the one at the create (every step count here is whole frames), then
    over the 0.5 s after tug_2 is created 4 m ahead, dropping onto its wheels."""
    with running_server("empty", seed=seed, extra=WATCHED) as sim:
        images = _watch_front_camera(sim)
        (x, y, _), _ = sim.pose()
        created = round(sim.step(0)["sim_time"] * 1e9)
        request = {"sdf_filename": str(TUG_SDF), "name": "tug_2", "namespace": "tug_2", "pose": _pose(x + 4.0, y)}
        assert sim.call("create", request, timeout=60.0)["ok"] is True
        sim.step(500)
        last = created + 5 * FRAME_NS
        frames = images.wait_for(lambda msgs: any(stamp_ns(m) == last for m in msgs), what="0.5 s of frames")
        return {stamp_ns(m): bytes(m.data) for m in frames if stamp_ns(m) >= created}


def test_images_across_a_create_are_byte_identical_run_to_run() -> None:
    """Two lockstep runs with one seed and the same calls: the camera that watches a tug created in front of it
    gives the same frames, byte for byte: the one at the create and the five after it, which show the tug."""
    first, second = _frames_across_a_create(3), _frames_across_a_create(3)
    assert len(first) == 6 and first.keys() == second.keys()
    for stamp in first:
        assert first[stamp] == second[stamp], f"the frames stamped {stamp} differ"
    empty = first[min(first)]
    assert all(first[stamp] != empty for stamp in sorted(first)[1:]), "the created tug is not in the images"
