"""Every fact of SPEC §1, read back from urdf/flexley_tug.sdf through the SDF reader."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROBOT_SDF

from simbot.description import Model, load_model
from simbot.description.lidar_params import LidarParams
from simbot.description.model import Box, Cylinder, Sphere
from simbot.description.poses import Pose
from simbot.sim.systems.camera import CameraParams
from simbot.sim.systems.imu import ImuParams

PI = math.pi
TOL = 1e-9


@pytest.fixture(scope="module")
def robot() -> Model:
    return load_model(ROBOT_SDF)


def _close(actual: tuple[float, ...], expected: tuple[float, ...], tol: float = TOL) -> bool:
    return bool(np.allclose(actual, expected, atol=tol))


def _yaw(pose: Pose) -> float:
    return math.atan2(math.sin(pose.rpy[2]), math.cos(pose.rpy[2]))


def test_frames_and_chassis(robot: Model) -> None:
    """base_footprint is the massless canonical link; base_link is 0.09 up with the chassis facts."""
    assert robot.canonical_link == "base_footprint" and robot.links[0].name == "base_footprint"
    assert robot.link("base_footprint").inertial is None
    base = robot.link("base_link")
    assert _close(base.pose.xyz, (0, 0, 0.09)) and _close(base.pose.rpy, (0, 0, 0))
    assert robot.joint("base_joint").type == "fixed" and robot.joint("base_joint").parent == "base_footprint"
    assert base.inertial is not None and base.inertial.mass == 100
    assert _close(base.inertial.inertia, (2.0833, 0, 0, 36.75, 0, 38.83))
    (collision,) = base.collisions
    assert isinstance(collision.geometry, Box) and _close(collision.geometry.size, (2.1, 0.5, 0.23))
    assert _close((base.pose @ collision.pose).xyz, (0, 0, 0.09))
    (visual,) = base.visuals
    assert visual.geometry.scale == (0.001, 0.001, 0.001) and visual.geometry.path is not None  # type: ignore[union-attr]


def test_imu(robot: Model) -> None:
    """imu_link is fixed 0.06 above base_link; 200 Hz; noise σ 2e-4 rad/s and 1.7e-2 m/s² per axis."""
    imu_link = robot.link("imu_link")
    assert _close((robot.link("base_link").pose.inverse() @ imu_link.pose).xyz, (0, 0, 0.06))
    assert robot.joint("imu_joint").type == "fixed" and robot.joint("imu_joint").parent == "base_link"
    (sensor,) = imu_link.sensors
    assert (
        sensor.type == "imu"
        and sensor.update_rate == 200
        and sensor.topic == "imu_scan"
        and sensor.frame_name == "imu_link"
    )
    imu = ImuParams.from_sdf(sensor)
    for noise in imu.angular_velocity_noise:
        assert noise.type == "gaussian" and noise.mean == 0 and noise.stddev == 2e-4
    for noise in imu.linear_acceleration_noise:
        assert noise.type == "gaussian" and noise.stddev == 1.7e-2


@pytest.mark.parametrize(
    ("side", "link_xyz", "link_yaw", "sensor_xyz", "sensor_x", "looks"),
    [
        ("front", (1.0, 0, 0.04), PI, (0.01, 0, 0.22), 0.99, 1.0),
        ("back", (-0.9, 0, 0.04), 0.0, (-0.05, 0, 0.22), -0.95, -1.0),
    ],
)
def test_lidars(
    robot: Model,
    side: str,
    link_xyz: tuple[float, ...],
    link_yaw: float,
    sensor_xyz: tuple[float, ...],
    sensor_x: float,
    looks: float,
) -> None:
    """Lidar links and sensors where SPEC puts them, looking forward (front) and backward (back)."""
    link = robot.link(f"base_scan_{side}")
    assert _close(link.pose.xyz, link_xyz) and abs(abs(_yaw(link.pose)) - abs(link_yaw)) < TOL
    assert link.inertial is not None and link.inertial.mass == 1.17
    (collision,) = link.collisions
    assert isinstance(collision.geometry, Cylinder) and (collision.geometry.radius, collision.geometry.length) == (
        0.05,
        0.05,
    )
    (sensor,) = link.sensors
    assert sensor.type == "gpu_lidar" and sensor.update_rate == 5 and sensor.frame_name == f"base_scan_{side}"
    assert sensor.topic == f"lidar_{side}"
    assert _close(sensor.pose.xyz, sensor_xyz) and abs(abs(_yaw(sensor.pose)) - PI) < TOL
    in_model = link.pose @ sensor.pose
    assert math.isclose(in_model.xyz[0], sensor_x, abs_tol=TOL)
    assert math.isclose(math.cos(_yaw(in_model)), looks, abs_tol=TOL)
    lidar = LidarParams.from_sdf(sensor)
    assert lidar.horizontal.samples == 720
    assert (lidar.horizontal.min_angle, lidar.horizontal.max_angle) == (-1.396263, 1.396263)
    assert (lidar.range_min, lidar.range_max, lidar.range_resolution) == (0.08, 10.0, 0.01)


CAMERAS = {
    "camera_front": (1.0, 0.0, 0.0),
    "camera_back": (-1.0, 0.0, PI),
    "camera_front_right": (1.0, -0.5, -PI / 2),
    "camera_back_right": (-1.0, -0.5, -PI / 2),
    "camera_front_left": (1.0, 0.5, PI / 2),
    "camera_back_left": (-1.0, 0.5, PI / 2),
}


def test_cameras(robot: Model) -> None:
    """Six 640×480 R8G8B8 cameras on base_link at z 0.39, 120° FOV, clip 0.05–50, 30 Hz."""
    cameras = {s.name: s for s in robot.link("base_link").sensors if s.type == "camera"}
    assert set(cameras) == set(CAMERAS)
    for name, (x, y, yaw) in CAMERAS.items():
        sensor = cameras[name]
        assert _close(sensor.pose.xyz, (x, y, 0.39)) and math.isclose(
            math.cos(_yaw(sensor.pose) - yaw), 1.0, abs_tol=TOL
        )
        camera = CameraParams.from_sdf(sensor)
        assert (camera.width, camera.height, camera.format) == (640, 480, "R8G8B8")
        assert (camera.horizontal_fov, camera.near, camera.far, sensor.update_rate) == (2.0944, 0.05, 50, 30)
        assert sensor.topic == name


@pytest.mark.parametrize("name", ["front_left", "front_right", "back_left", "back_right"])
def test_wheels(robot: Model, name: str) -> None:
    """Wheels at (±0.58, ±0.2, −0.02), r 0.075, l 0.05 about y, 0.765 kg, μ 0.9 along and 0.25 across."""
    x = 0.58 if name.startswith("front") else -0.58
    y = 0.2 if name.endswith("left") else -0.2
    link = robot.link(f"{name}_wheel")
    assert _close(link.pose.xyz, (x, y, -0.02))
    assert link.inertial is not None and link.inertial.mass == 0.765
    (collision,) = link.collisions
    geometry = collision.geometry
    assert isinstance(geometry, Cylinder) and (geometry.radius, geometry.length) == (0.075, 0.05)
    cylinder_axis = collision.pose.matrix()[:3, 2]
    assert _close(tuple(abs(cylinder_axis)), (0, 1, 0))
    friction = collision.friction
    assert friction is not None and (friction.mu, friction.mu2) == (0.9, 0.25)
    assert friction.fdir1 is not None
    along = collision.pose.matrix()[:3, :3] @ np.array(friction.fdir1)
    assert _close(tuple(abs(along)), (1, 0, 0))  # mu acts along the rolling direction
    joint = robot.joint(f"{name}_wheel_joint")
    assert joint.type == "revolute" and joint.parent == "base_link" and joint.axis is not None
    assert _close(joint.axis.xyz, (0, 1, 0)) and joint.axis.lower is None and joint.axis.upper is None
    assert (joint.axis.effort, joint.axis.velocity) == (10000, 100)
    assert joint.pose == link.pose


@pytest.mark.parametrize(
    ("name", "x", "y"),
    [
        ("front_right", 0.92, -0.17),
        ("front_left", 0.92, 0.17),
        ("back_right", -0.79, -0.17),
        ("back_left", -0.79, 0.17),
    ],
)
def test_castors(robot: Model, name: str, x: float, y: float) -> None:
    """Castors: spheres r 0.025, 0.103 kg, on ball joints at z −0.05."""
    link = robot.link(f"castor_{name}")
    assert _close(link.pose.xyz, (x, y, -0.05))
    assert link.inertial is not None and link.inertial.mass == 0.103
    (collision,) = link.collisions
    assert isinstance(collision.geometry, Sphere) and collision.geometry.radius == 0.025
    assert robot.joint(f"castor_{name}_joint").type == "ball"


def test_plugins(robot: Model) -> None:
    """DiffDrive, JointStatePublisher and DetachableJoint with the parameters of SPEC §1."""
    plugins = {p.name.rsplit("::", 1)[-1]: p for p in robot.plugins}
    drive = plugins["DiffDrive"]
    assert drive.get_all("left_joint") == ["front_left_wheel_joint", "back_left_wheel_joint"]
    assert drive.get_all("right_joint") == ["front_right_wheel_joint", "back_right_wheel_joint"]
    assert float(drive.get("wheel_separation") or 0) == 0.4 and float(drive.get("wheel_radius") or 0) == 0.075
    assert drive.get("topic") == "cmd_vel" and drive.get("odom_topic") == "odom"
    assert drive.get("frame_id") == "odom" and float(drive.get("odom_publish_frequency") or 0) == 50
    joints = plugins["JointStatePublisher"]
    assert joints.get_all("joint_name") == ["front_left_wheel_joint", "front_right_wheel_joint"]
    assert float(joints.get("update_rate") or 0) == 30
    dock = plugins["DetachableJoint"]
    assert (dock.get("parent_link"), dock.get("child_model"), dock.get("child_link")) == (
        "base_link",
        "trolley",
        "base",
    )
    assert (dock.get("attach_topic"), dock.get("detach_topic")) == ("attach", "detach")
    assert dock.get("output_topic") == "detachable_joint/state"
