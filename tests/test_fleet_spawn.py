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
"""

from __future__ import annotations

import json
import math
import subprocess
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from conftest import REPO
from server_helpers import (
    SimServer,
    keyed_payload,
    planar_distance,
    raw_samples,
    render_workers,
    running_server,
    server_command,
    wait_until,
)

from simbot.bus import messages
from simbot.bus.graph import discover

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


def test_remove_takes_its_keys_off_the_graph(fleet: SimServer) -> None:
    """tug_9 removed: no key under tug_9/ nor its model/tug_9/pose is left; tug_8's keys are all there."""

    def under(prefix: str) -> set[str]:
        return {e.key for e in discover(fleet.node.session, fleet.namespace) if f"/{prefix}/" in f"/{e.key}"}

    assert f"{fleet.namespace}/tug_9/cmd_vel" in under("tug_9")
    tug_8 = under("tug_8")
    assert fleet.call("remove", {"name": "tug_9"}) == {"ok": True, "name": "tug_9"}
    assert under("tug_9") == set()
    assert under("tug_8") == tug_8
    assert "tug_9" not in fleet.state()["models"]
    fleet.step(10)


def _run_with_a_create(seed: int) -> dict[str, list[bytes]]:
    """Every message of a lockstep run that creates a tug after 100 steps and drives it for 400: by key, in order."""
    with running_server("empty", seed=seed, extra=CHEAP_CAMERAS) as sim:
        prefix = len(sim.namespace) + 1
        with raw_samples(sim.node.session, f"{sim.namespace}/**", keyed_payload) as received:
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
    detached, its render workers end; once the workers run, a create with cameras is refused;
    a reset removes the trolley, created at run time too."""
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
        refused = create_tug(sim, 2)
        assert refused["ok"] is False and refused["error"].startswith("sdf") and "render workers" in refused["error"]
        assert "tug_2" not in sim.state()["models"]
        assert sim.call("remove", {"name": "tug_1"}) == {"ok": True, "name": "tug_1"}
        state.wait_for(lambda msgs: msgs[-1].data == "detached", what="detached on removal")
        wait_until(lambda: not render_workers(sim.process.pid), 10.0, "the render workers to end")
        sim.step(100)
        assert set(sim.state()["models"]) == {"ground_plane", "trolley"}
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
