"""What a running server says about the robot: `robot_description` (URDF) and `tf_static` agree with the SDF.

Both are latched: this test's client subscribes after the server published them (a late joiner)
and must still get them. The URDF is parsed with yourdfpy and its forward kinematics at the zero
configuration must put every SDF link where the SDF does (link.pose, in the model frame); the
tf_static tree, composed from base_footprint, must put every fixed link and every sensor frame
where the SDF does, and hold the facts of SPEC §1 (base_link 0.09 up, six cameras at z 0.39).
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

import numpy as np
import pytest
import yourdfpy
from conftest import ROBOT_SDF
from server_helpers import (
    JOINT_STATE,
    STRING,
    TF_MESSAGE,
    Collector,
    SimServer,
    module_server,
    stamp_ns,
)

from simbot.bus import Node
from simbot.bus.frames import optical_frame
from simbot.description import load_model
from simbot.description.model import Model
from simbot.description.poses import Pose
from simbot.description.urdf_writer import link_frame
from simbot.sim.physics import ball_castors
from simbot.transform import quaternion_to_matrix

TOL = 1e-6
ROOT = "base_footprint"
CAMERAS = {
    "camera_front": (1.0, 0.0, 0.0),
    "camera_back": (-1.0, 0.0, math.pi),
    "camera_front_right": (1.0, -0.5, -math.pi / 2),
    "camera_back_right": (-1.0, -0.5, -math.pi / 2),
    "camera_front_left": (1.0, 0.5, math.pi / 2),
    "camera_back_left": (-1.0, 0.5, math.pi / 2),
}


sim = module_server("warehouse")


@pytest.fixture(scope="module")
def model() -> Model:
    return load_model(ROBOT_SDF)


@pytest.fixture
def client_node(sim: SimServer) -> Iterator[Node]:
    """A fresh client node on the bus of the module's server (a late joiner)."""
    with sim.client() as node:
        yield node


@pytest.fixture
def urdf_text(client_node: Node) -> str:
    got: Collector[Any] = Collector()
    client_node.subscribe("robot_description", STRING, got, latched=True)
    return str(got.wait_count(1, what="robot_description for a late joiner")[0].data)


@pytest.fixture
def tf_static(client_node: Node) -> dict[str, tuple[str, np.ndarray]]:
    """child frame → (parent frame, 4×4 transform of the child in the parent)."""
    got: Collector[Any] = Collector()
    client_node.subscribe("tf_static", TF_MESSAGE, got, latched=True)
    message = got.wait_count(1, what="tf_static for a late joiner")[0]
    tree: dict[str, tuple[str, np.ndarray]] = {}
    for transform in message.transforms:
        child = transform.child_frame_id
        assert child not in tree, f"tf_static gives {child!r} two parents"
        t, r = transform.transform.translation, transform.transform.rotation
        assert abs(math.sqrt(r.x**2 + r.y**2 + r.z**2 + r.w**2) - 1.0) < 1e-9, (
            f"{child}: rotation is not a unit quaternion"
        )
        matrix = np.eye(4)
        matrix[:3, :3] = quaternion_to_matrix((r.x, r.y, r.z, r.w))
        matrix[:3, 3] = (t.x, t.y, t.z)
        tree[child] = (transform.header.frame_id, matrix)
    return tree


def _in_root(tree: dict[str, tuple[str, np.ndarray]], frame: str) -> np.ndarray:
    """The pose of `frame` in base_footprint, composed along tf_static."""
    matrix = np.eye(4)
    seen: list[str] = []
    while frame != ROOT:
        assert frame in tree, f"tf_static does not connect {frame!r} to {ROOT} (chain {' <- '.join(seen + [frame])})"
        assert frame not in seen, f"tf_static has a cycle through {frame!r}"
        seen.append(frame)
        parent, transform = tree[frame]
        matrix = transform @ matrix
        frame = parent
    return matrix


def _close(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max())


def test_robot_description_matches_the_sdf(urdf_text: str, model: Model) -> None:
    urdf = yourdfpy.URDF.load(
        io.StringIO(urdf_text), build_scene_graph=True, load_meshes=False, load_collision_meshes=False
    )
    assert urdf.validate(), "yourdfpy rejects the URDF on robot_description"
    assert urdf.base_link == ROOT
    assert model.link(ROOT).pose.is_identity()
    for link in model.links:
        assert link.name in urdf.link_map, f"the URDF lacks the SDF link {link.name!r}"
        fk = urdf.get_transform(link.name, urdf.base_link)
        error = _close(fk, link_frame(link).matrix())
        assert error < TOL, f"{link.name}: URDF forward kinematics differs from the SDF pose by {error:.2e}"
        inertial = urdf.link_map[link.name].inertial
        if link.inertial is not None:
            assert inertial is not None and inertial.mass == pytest.approx(link.inertial.mass)
    wheels = {j.name: j for j in urdf.robot.joints if j.name.endswith("_wheel_joint")}
    assert sorted(wheels) == sorted(
        f"{w}_wheel_joint" for w in ("front_left", "front_right", "back_left", "back_right")
    )
    for joint in wheels.values():
        assert joint.type in ("continuous", "revolute")
        axis_in_root = urdf.get_transform(joint.child, ROOT)[:3, :3] @ np.asarray(joint.axis)
        assert abs(abs(axis_in_root[1]) - 1.0) < TOL, f"{joint.name}: axis {axis_in_root} is not along y"
    assert urdf.link_map["base_link"].inertial.mass == pytest.approx(100.0)


def test_tf_static_matches_the_sdf(tf_static: dict[str, tuple[str, np.ndarray]], model: Model) -> None:
    tree = tf_static
    # the facts of SPEC §1, edge by edge
    parent, matrix = tree["base_link"]
    assert parent == ROOT and _close(matrix, Pose((0.0, 0.0, 0.09), (0.0, 0.0, 0.0)).matrix()) < TOL
    parent, matrix = tree["imu_link"]
    assert parent == "base_link" and _close(matrix, Pose((0.0, 0.0, 0.06), (0.0, 0.0, 0.0)).matrix()) < TOL
    # a lidar's frame is where its sensor is (SPEC §1: x 0.99 looking forward, x -0.95 looking back,
    # 0.22 above a link 0.04 up), so its scans are where the rays start
    for lidar, (x, yaw) in {"base_scan_front": (0.99, 0.0), "base_scan_back": (-0.95, math.pi)}.items():
        expected = Pose((x, 0.0, 0.26), (0.0, 0.0, yaw)).matrix()
        assert _close(_in_root(tree, lidar), expected) < TOL, f"{lidar} is not where SPEC §1 puts its sensor"
    for camera, (x, y, yaw) in CAMERAS.items():
        assert camera in tree, f"tf_static lacks the camera frame {camera!r}"
        parent, matrix = tree[camera]
        assert parent == "base_link", f"{camera} hangs from {parent!r}, not base_link"
        assert _close(matrix, Pose((x, y, 0.39), (0.0, 0.0, yaw)).matrix()) < TOL, (
            f"{camera} is not at ({x}, {y}, 0.39) yaw {yaw:.4f}"
        )
        parent, optical = tree[optical_frame(camera)]
        assert parent == camera and np.allclose(optical[:3, 3], 0.0), f"{camera}'s optical frame is not at the camera"
        # z forward, x right, y down: the camera's x, -y, -z
        assert np.allclose(optical[:3, :3], [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-9), (
            f"{camera}'s optical frame is turned wrong"
        )

    # every fixed link and every sensor frame, composed from base_footprint, where the SDF puts it; the
    # castors too, whose gimbals the physics holds fixed (Physics.fixed_castors): tf_static at zero
    castors = {j.child for j in model.joints if j.name in ball_castors(model)}
    fixed = {j.child for j in model.joints if j.type == "fixed"} | castors
    checked = []
    for link in model.links:
        if link.name in fixed:
            error = _close(_in_root(tree, link.name), link_frame(link).matrix())
            assert error < TOL, f"tf_static puts {link.name} {error:.2e} from its SDF pose"
            checked.append(link.name)
        for sensor in link.sensors:
            frame = sensor.frame_name or sensor.name
            expected = (
                link.pose @ sensor.pose
            ).matrix()  # the lidars' and the IMU's frames are their links'; they sit here too
            error = _close(_in_root(tree, frame), expected)
            assert error < TOL, f"tf_static puts {frame} {error:.2e} from the SDF pose of sensor {sensor.name}"
            checked.append(frame)
    assert {"base_link", "imu_link", "base_scan_front", "base_scan_back"} <= set(checked)
    assert set(CAMERAS) <= set(checked) and castors <= set(checked) and len(castors) == 4
    # static means static: no wheel (they move) and nothing from the odom tree
    movable = {j.child for j in model.joints if j.type != "fixed"} - castors
    assert not movable & set(tree), f"tf_static holds moving links: {sorted(movable & set(tree))}"
    assert "odom" not in tree and ROOT not in tree


def test_tf_static_and_robot_description_agree(urdf_text: str, tf_static: dict[str, tuple[str, np.ndarray]]) -> None:
    """Every tf_static frame that is a URDF link sits where the URDF's kinematics puts it."""
    urdf = yourdfpy.URDF.load(
        io.StringIO(urdf_text), build_scene_graph=True, load_meshes=False, load_collision_meshes=False
    )
    shared = [frame for frame in tf_static if frame in urdf.link_map]
    assert len(shared) >= 4
    for frame in shared:
        error = _close(_in_root(tf_static, frame), urdf.get_transform(frame, ROOT))
        assert error < TOL, f"{frame}: tf_static and robot_description differ by {error:.2e}"


def test_robot_description_names_meshes_a_ros_host_finds(urdf_text: str) -> None:
    """RViz on the same machine loads the meshes: `file://` URIs of files that exist."""
    uris = [mesh.get("filename", "") for mesh in ET.fromstring(urdf_text).iter("mesh")]
    assert uris, "robot_description names no mesh"
    for uri in uris:
        parsed = urlparse(uri)
        assert parsed.scheme == "file", f"{uri!r} is not a file:// URI"
        assert Path(unquote(parsed.path)).is_file(), f"{uri!r} names no file"


def _tf_tree(messages: list[Any]) -> dict[str, tuple[str, np.ndarray]]:
    """child → (parent, transform) from TFMessages, the latest of each child winning (as a tf buffer keeps it)."""
    tree: dict[str, tuple[str, np.ndarray]] = {}
    for message in messages:
        for transform in message.transforms:
            t, r = transform.transform.translation, transform.transform.rotation
            matrix = np.eye(4)
            matrix[:3, :3] = quaternion_to_matrix((r.x, r.y, r.z, r.w))
            matrix[:3, 3] = (t.x, t.y, t.z)
            tree[transform.child_frame_id] = (transform.header.frame_id, matrix)
    return tree


def test_every_link_is_reachable_from_odom_and_the_wheels_turn_in_tf(
    sim: SimServer, client_node: Node, urdf_text: str, tf_static: dict[str, tuple[str, np.ndarray]]
) -> None:
    """RViz's view: tf_static plus tf connect every URDF link (wheels, castor parts) to odom, the movable
    joints at the joint-state rate (30 Hz: 3 messages in 0.1 s of sim time besides odom's 5), and a front
    wheel's transform after a drive is what the URDF's kinematics gives at its joint_states position."""
    tf: Collector[Any] = Collector()
    states: Collector[Any] = Collector()
    client_node.subscribe("tf", TF_MESSAGE, tf)
    client_node.subscribe("joint_states", JOINT_STATE, states)
    sim.prime(tf, states)
    sim.drive(0.5)
    sim.step(1000)
    sim.drive(0.0)
    tf.clear()
    sim.step(100)
    messages = tf.wait_for(lambda m: len(m) >= 8, what="odom and joint transforms for 0.1 s")
    joints = [m for m in messages if m.transforms[0].header.frame_id not in ("odom", "world")]  # world: the scene's
    assert len(joints) == 3, f"{len(joints)} joint transform messages in 0.1 s of sim time, not 3 (30 Hz)"
    urdf = yourdfpy.URDF.load(
        io.StringIO(urdf_text), build_scene_graph=True, load_meshes=False, load_collision_meshes=False
    )
    tree = {**tf_static, **_tf_tree(messages)}
    for link in urdf.link_map:
        frame, chain = link, [link]
        while frame != "odom":
            assert frame in tree, f"{link} does not reach odom: the chain {' <- '.join(chain)} stops"
            frame = tree[frame][0]
            chain.append(frame)
    last = joints[-1]
    stamp = stamp_ns(last.transforms[0])
    state = states.wait_stamp(stamp, what="joint_states at the tf stamp")
    positions = dict(zip(state.name, state.position))
    assert abs(positions["front_left_wheel_joint"]) > 5.0, (
        "the wheel did not turn in 1 s at 0.5 m/s (0.5 / 0.075 rad/s)"
    )
    urdf.update_cfg({name: positions[name] for name in ("front_left_wheel_joint", "front_right_wheel_joint")})
    for name in ("front_left_wheel_joint", "front_right_wheel_joint"):
        joint = urdf.joint_map[name]
        parent, matrix = _tf_tree([last])[joint.child]
        assert parent == joint.parent
        error = _close(matrix, urdf.get_transform(joint.child, joint.parent))
        assert error < TOL, f"{name}: tf differs from the URDF's kinematics at {positions[name]:.3f} rad by {error:.2e}"
    sim.reset()
