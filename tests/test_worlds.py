"""The shipped worlds: physics settings, the warehouse's layout, its colours, and room for the robot to drive."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from simbot.description import Model, World, load_model, load_world
from simbot.description.model import RGBA, Box, Cylinder, Geometry, Plane, Sphere
from simbot.description.poses import IDENTITY, Pose
from simbot.description.resources import RESOURCE_PATH_VARIABLES

REPO = Path(__file__).resolve().parents[1]
WORLDS = REPO / "worlds"
ROBOT_SDF = REPO / "urdf" / "flexley_tug.sdf"
CORRIDOR = (np.array([-6.0, -1.8, 0.01]), np.array([4.5, 1.8, 3.0]))
"""The robot's lane in the warehouse, from behind its start box to past the trolley: kept free."""

Aabb = tuple[np.ndarray, np.ndarray]


@pytest.fixture(autouse=True)
def own_resources_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """model:// must resolve to simbot's worlds/models, not to a Gazebo setup of the machine."""
    for variable in RESOURCE_PATH_VARIABLES:
        monkeypatch.delenv(variable, raising=False)


def load(name: str, caplog: pytest.LogCaptureFixture) -> World:
    """A repo world, failing on any warning the loader logs (e.g. a mesh it cannot find)."""
    with caplog.at_level(logging.WARNING):
        world = load_world(WORLDS / name)
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert warnings == [], warnings
    return world


def half_extents(geometry: Geometry) -> np.ndarray:
    """Half sizes along the shape's own axes; cylinders and spheres as their bounding boxes."""
    if isinstance(geometry, Box):
        return np.asarray(geometry.size) / 2
    if isinstance(geometry, Cylinder):
        return np.array([geometry.radius, geometry.radius, geometry.length / 2])
    assert isinstance(geometry, Sphere), f"no bounding box for {geometry!r}"
    return np.full(3, geometry.radius)


def aabb(pose: Pose, geometry: Geometry) -> Aabb:
    """World-axis bounding box of a shape placed at `pose`: |R| h gives the rotated half extents."""
    mat = pose.matrix()
    half = np.abs(mat[:3, :3]) @ half_extents(geometry)
    return mat[:3, 3] - half, mat[:3, 3] + half


def collision_boxes(model: Model, placement: Pose | None = None) -> dict[str, Aabb]:
    """Each collision's world AABB (planes skipped), composing placement @ link pose @ collision pose."""
    base = model.pose if placement is None else placement
    return {
        f"{model.name}/{link.name}/{c.name}": aabb(base @ link.pose @ c.pose, c.geometry)
        for link in model.links
        for c in link.collisions
        if not isinstance(c.geometry, Plane)
    }


def overlaps(a: Aabb, b: Aabb, axes: slice = slice(0, 3)) -> bool:
    """True when two boxes share volume along the given axes."""
    return bool(np.all(a[0][axes] < b[1][axes]) and np.all(b[0][axes] < a[1][axes]))


@pytest.mark.parametrize("name", ["empty.sdf", "warehouse.sdf"])
def test_physics_settings(name: str, caplog: pytest.LogCaptureFixture) -> None:
    """Both worlds load without warnings, step physics every 1 ms and pull at -9.8 m/s^2 along z."""
    world = load(name, caplog)
    assert world.physics.max_step_size == pytest.approx(0.001, abs=1e-9)
    np.testing.assert_allclose(world.gravity, (0.0, 0.0, -9.8), atol=1e-9)


def test_empty_world_has_ground_plane(caplog: pytest.LogCaptureFixture) -> None:
    """empty.sdf holds a static ground plane whose collision is an upward-facing plane."""
    ground = load("empty.sdf", caplog).model("ground_plane")
    assert ground.static
    planes = [c.geometry for link in ground.links for c in link.collisions if isinstance(c.geometry, Plane)]
    assert len(planes) == 1
    np.testing.assert_allclose(planes[0].normal, (0.0, 0.0, 1.0), atol=1e-9)


def test_warehouse_hall_is_20_by_20(caplog: pytest.LogCaptureFixture) -> None:
    """The walls' collision boxes enclose x, y in [-10, 10] m (within 0.5 m) and stand at least 2 m tall."""
    world = load("warehouse.sdf", caplog)
    walls = list(collision_boxes(world.model("walls")).values())
    lo, hi = np.min([b[0] for b in walls], axis=0), np.max([b[1] for b in walls], axis=0)
    np.testing.assert_allclose(lo[:2], (-10.0, -10.0), atol=0.5)
    np.testing.assert_allclose(hi[:2], (10.0, 10.0), atol=0.5)
    assert hi[2] >= 2.0, f"walls only {hi[2]} m high"


def test_warehouse_furniture(caplog: pytest.LogCaptureFixture) -> None:
    """The hall holds >= 4 racks, >= 2 work cells, >= 4 bins and >= 4 pillars, each from its model:// URI."""
    world = load("warehouse.sdf", caplog)
    uris = [m.uri for m in world.models]
    for uri, least in {"model://rack": 4, "model://workcell": 2, "model://bin": 4, "model://pillar": 4}.items():
        assert uris.count(uri) >= least, f"{uris.count(uri)} x {uri}"


def test_trolley(caplog: pytest.LogCaptureFixture) -> None:
    """The trolley is a dynamic 5 kg model with link 'base', parked at (1, 0.2, 0), unrotated."""
    trolley = load("warehouse.sdf", caplog).model("trolley")
    assert trolley.uri == "model://trolley"
    assert not trolley.static
    base = trolley.link("base")
    assert base.inertial is not None
    assert base.inertial.mass == pytest.approx(5.0, abs=1e-9)
    np.testing.assert_allclose(trolley.pose.xyz, (1.0, 0.2, 0.0), atol=1e-9)
    np.testing.assert_allclose(trolley.pose.rpy, (0.0, 0.0, 0.0), atol=1e-9)


@pytest.mark.parametrize("name", ["empty.sdf", "warehouse.sdf"])
def test_every_visual_is_coloured(name: str, caplog: pytest.LogCaptureFixture) -> None:
    """Every visual has a material with a colour, and the warehouse is not all one colour."""
    world = load(name, caplog)
    visuals = {f"{m.name}/{link.name}/{v.name}": v for m in world.models for link in m.links for v in link.visuals}
    colours: dict[str, RGBA | None] = {k: v.material.color() if v.material else None for k, v in visuals.items()}
    assert colours and [k for k, c in colours.items() if c is None] == []
    assert len(set(colours.values())) > 1 or name == "empty.sdf"


def test_corridor_is_clear(caplog: pytest.LogCaptureFixture) -> None:
    """No static collision reaches into the lane x in [-6, 4.5], |y| <= 1.8, z in [0.01, 3]."""
    world = load("warehouse.sdf", caplog)
    boxes = {k: v for m in world.models if m.static for k, v in collision_boxes(m).items()}
    assert len(boxes) > 20
    blocking = sorted(k for k, box in boxes.items() if overlaps(box, CORRIDOR))
    assert blocking == []


def test_robot_drives_under_the_trolley(caplog: pytest.LogCaptureFixture) -> None:
    """The robot on its wheels at y = 0, swept along x, misses every trolley collision (chassis and
    lidars included), and the deck's underside is >= 0.1 m above the chassis top (0.30 m)."""
    robot = load_model(ROBOT_SDF)
    wheels = [b for k, b in collision_boxes(robot, IDENTITY).items() if "wheel" in k]
    assert len(wheels) == 4
    height = -min(float(b[0][2]) for b in wheels)
    assert height == pytest.approx(0.075 + 0.02, abs=1e-6)
    robot_boxes = collision_boxes(robot, Pose((0.0, 0.0, height)))
    chassis = robot_boxes["flexley_tug/base_link/base_link_collision"]
    assert chassis[1][2] == pytest.approx(0.30, abs=1e-6)
    assert sum("base_scan" in k for k in robot_boxes) == 2
    trolley = collision_boxes(load("warehouse.sdf", caplog).model("trolley"))
    hits = [(r, t) for r, rb in robot_boxes.items() for t, tb in trolley.items() if overlaps(rb, tb, slice(1, 3))]
    assert hits == []
    deck_underside = float(trolley["trolley/base/deck_collision"][0][2])
    assert deck_underside - float(chassis[1][2]) >= 0.1 - 1e-9
