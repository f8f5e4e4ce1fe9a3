"""The original Gazebo robot and warehouse load unmodified: warnings for missing meshes, no error."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from simbot.description import load_model, load_world
from simbot.description.lidar_params import LidarParams
from simbot.description.model import Cylinder
from simbot.sim.systems.imu import ImuParams

MISSING_MESH = "not found (tried"


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


def test_reference_robot(reference: Path, clean_resource_path: None, caplog: pytest.LogCaptureFixture) -> None:
    """Two lidars, six cameras and an IMU with the SDF's own parameters; missing meshes fall back."""
    caplog.set_level(logging.WARNING)
    robot = load_model(reference / "urdf" / "Flexley_Tug.sdf")
    sensors = {s.name: s for _, s in robot.sensors()}
    assert sorted(s.type for s in sensors.values()) == ["camera"] * 6 + ["gpu_lidar"] * 2 + ["imu"]
    assert LidarParams.from_sdf(sensors["lidar_front"]).horizontal.samples == 720
    assert ImuParams.from_sdf(sensors["imu_sensor"]).linear_acceleration_noise[2].stddev == 1.7e-2
    warnings = _warnings(caplog)
    assert len(warnings) == 11 and all(MISSING_MESH in w for w in warnings)  # 11 mesh visuals, none shipped
    assert any("chassis.stl" in w and "urdf/../meshes/chassis.stl" in w for w in warnings), "names the paths tried"
    wheel = robot.link("front_left_wheel")
    assert isinstance(wheel.visuals[0].geometry, Cylinder) and wheel.visuals[0].pose == wheel.collisions[0].pose


def test_reference_warehouse(
    reference: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The warehouse resolves model://trolley on GZ_SIM_RESOURCE_PATH and keeps the first <physics>."""
    caplog.set_level(logging.WARNING)
    monkeypatch.delenv("SIMBOT_RESOURCE_PATH", raising=False)
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(reference / "models"))
    world = load_world(reference / "worlds" / "warehouse.sdf")
    trolley = world.model("trolley")
    assert trolley.uri == "model://trolley" and not trolley.static
    assert trolley.pose.xyz == (1.0, 0.2, 0.55) and trolley.pose.rpy[0] == pytest.approx(1.5708)
    assert trolley.links[0].inertial is not None and trolley.links[0].inertial.mass == 5
    assert trolley.links[0].collisions[0].geometry.path.name == "DOLLEYASSY_1.stl"  # type: ignore[union-attr]
    assert world.physics.max_step_size == 0.001 and len(world.models) == 8  # workcell, six bins, trolley
    warnings = _warnings(caplog)
    assert warnings and all(MISSING_MESH in w for w in warnings)
    assert any("DOLLEYASSY.stl" in w for w in warnings) and any("mesh.dae" in w for w in warnings)


def test_reference_empty_world(reference: Path) -> None:
    """The empty world: 1 ms physics, a ground plane, its plugins recognised as plain data."""
    world = load_world(reference / "worlds" / "empty.sdf")
    assert world.physics.max_step_size == 0.001 and world.model("ground_plane").static
    assert any(p.name.endswith("TriggeredPublisher") for p in world.plugins)
