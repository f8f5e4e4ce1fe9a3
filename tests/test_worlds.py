"""The shipped worlds: physics settings, the warehouse's layout, its colours, and room for the robot to drive."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest

from simbot.description import Model, World, load_model, load_world
from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import PROXY_RADIUS, ActorModel
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


PERSON_CLEARANCE_M = 0.3
"""Metres at least between a walking worker's proxy (0.25 m about its axis) and any collision of the warehouse."""
CART_CLEARANCE_M = 0.4
"""Metres at least between the cart's side (0.3 m from its axis: it is pushed only while it faces its
next waypoint within 2°) and any collision along its legs, room for its sway and its overshoot past
a waypoint (under 0.1 m, tests/test_warehouse_people.py); turning on the spot at a corner, its
half diagonal (0.58 m) keeps 0.2 m."""


def planar_gap(point: np.ndarray, box: Aabb) -> float:
    """Distance in the floor plane from `point` to a box that stands between the floor and head height, else inf."""
    if box[1][2] <= 0.01 or box[0][2] >= 2.0:
        return float("inf")
    outside = np.maximum(np.maximum(box[0][:2] - point[:2], 0.0), point[:2] - box[1][:2])
    return float(np.linalg.norm(outside))


def warehouse_boxes(caplog: pytest.LogCaptureFixture) -> dict[str, Aabb]:
    """Every collision of the warehouse but the floor, the trolley's included."""
    world = load("warehouse.sdf", caplog)
    return {k: v for m in world.models if m.name != "floor" for k, v in collision_boxes(m).items()}


def test_the_plain_warehouse_holds_nothing_that_moves_by_itself(caplog: pytest.LogCaptureFixture) -> None:
    """No actor and no model plugin: the tests that need a still warehouse get one; the people come with --add."""
    world = load("warehouse.sdf", caplog)
    movers = [m.name for m in world.models if isinstance(m, ActorModel) or m.plugins]
    assert movers == []


def test_the_workers_walk_clear_of_racks_pillars_work_cells_and_the_trolley(caplog: pytest.LogCaptureFixture) -> None:
    """Each worker's script sampled every 50 ms over one round keeps its proxy clear of every collision."""
    boxes = warehouse_boxes(caplog)
    actors = [m for m in load("additions/warehouse_people.sdf", caplog).models if isinstance(m, ActorModel)]
    assert len(actors) == 3
    for actor in actors:
        path = ScriptPath.of(actor.script)
        round_s = sum(p.duration for p in path.paths)
        points = [actor.pose.matrix() @ (*path.pose_at(t).position, 1.0) for t in np.arange(0.0, round_s, 0.05)]
        gap, nearest = min((planar_gap(p, box), name) for p in points for name, box in boxes.items())
        assert gap - PROXY_RADIUS >= PERSON_CLEARANCE_M, f"{actor.name} walks {gap - PROXY_RADIUS:.2f} m from {nearest}"


def test_the_carts_loop_keeps_clear_and_crosses_the_tugs_lane_east_of_the_trolley(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The cart's legs, start to first waypoint and round its loop, and its turns at the corners keep it clear."""
    boxes = warehouse_boxes(caplog)
    cart = load("additions/warehouse_people.sdf", caplog).model("cart")
    (plugin,) = cart.plugins
    corners = [np.array([float(v) for v in p.text.split()]) for p in plugin.params[-1].children]
    legs = [np.array(cart.pose.xyz[:2]), *corners, corners[0]]
    half_width, half_diagonal = 0.3, math.hypot(0.5, 0.3)
    for a, b in zip(legs, legs[1:]):
        for p in np.linspace(a, b, 50):
            gap, nearest = min((planar_gap(p, box), name) for name, box in boxes.items())
            assert gap - half_width >= CART_CLEARANCE_M, (
                f"the cart passes {gap - half_width:.2f} m from {nearest} at {p}"
            )
    for corner in corners:
        gap, nearest = min((planar_gap(corner, box), name) for name, box in boxes.items())
        assert gap - half_diagonal >= 0.2, f"the cart turns {gap - half_diagonal:.2f} m from {nearest} at {corner}"
    assert min(c[0] for c in corners) > CORRIDOR[1][0], "the cart's loop reaches into the tug's lane west of x 4.5"
