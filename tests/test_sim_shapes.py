"""The SDF shapes in PyBullet: each settles where its geometry says, a heightmap's surface is where
its image says, a static polyline collides with its concave outline, nested links are found by name."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from conftest import settled_physics

from simbot.description import load_model, load_world
from simbot.description.resources import asset
from simbot.sim.physics import Physics
from simbot.sim.render.mesh_materials import submeshes

FIXTURES = Path(__file__).parent / "fixtures" / "gazebo"
SETTLE_STEPS = 3000
"""3 s at 1 ms: every shape dropped from 0.5 m is at rest by then."""
MESH_MARGIN = 1e-3
"""Bullet pads a convex-hull mesh with a collision margin of 1 mm: a mesh rests that much high."""
CONTACT_SLOP = 1e-4
"""A primitive rests sunk by a few hundredths of a millimetre (Bullet's contact penetration at 1 kg)."""


@pytest.fixture(scope="module")
def shapes() -> Iterator[Physics]:
    """tests/fixtures/gazebo/shapes.sdf, settled for 3 s."""
    yield from settled_physics(FIXTURES / "shapes.sdf", SETTLE_STEPS)


@pytest.mark.parametrize(
    ("model", "height", "tolerance"),
    [
        ("capsule", 0.1, CONTACT_SLOP),  # lying on its side: its radius
        ("ellipsoid", 0.1, MESH_MARGIN + CONTACT_SLOP),  # on its shortest radius
        ("cone", 0.15, MESH_MARGIN + CONTACT_SLOP),  # on its base: half its length
        ("ball", 1.0, CONTACT_SLOP),  # <sphere/>: SDF's radius of 1
    ],
)
def test_shape_rests_at_its_geometric_height(shapes: Physics, model: str, height: float, tolerance: float) -> None:
    """The model frame (the shape's centre) rests above the plane by what the shape's size gives."""
    (_, _, z), _ = shapes.model_pose(model)
    assert z == pytest.approx(height, abs=tolerance)
    assert z >= height - CONTACT_SLOP


def test_static_polyline_collides_with_its_concave_outline(shapes: Physics) -> None:
    """Rays down at the notch (−0.5..0.5 square less the triangle cut to its centre) fall through to
    the ground; beside it they stop on the top, 0.3 m up."""
    at = np.array([[0.3, 3.0], [-0.3, 3.0], [0.3, 3.4]])
    starts, ends = np.c_[at, np.full(3, 1.0)], np.c_[at, np.full(3, -1.0)]
    heights = 1.0 - 2.0 * shapes.cast_rays(starts, ends)
    assert np.allclose(heights, [0.0, 0.3, 0.3], atol=1e-6)


def test_heightfield_surface_is_the_images_surface() -> None:
    """Rays down on the heightfield hit z = 0.5 (model) + 0.2 (pos) + 0.51 (x + 2) + 0.1 (y + 2),
    the plane the ramp image encodes, at points between the pixels as well as on them."""
    world = load_world(FIXTURES / "heightmap.sdf")
    physics = Physics(world)
    physics.add_model(world.model("terrain"))
    points = np.array([[0.5, -0.7], [-1.5, 1.5], [1.9, -1.9], [0.0, 0.0], [-1.95, 1.95]])
    starts = np.c_[points + (1.0, 2.0), np.full(len(points), 10.0)]
    ends = starts * (1.0, 1.0, -1.0)
    heights = 10.0 - 20.0 * physics.cast_rays(starts, ends)
    physics.close()
    assert np.allclose(heights, 0.7 + 0.51 * (points[:, 0] + 2) + 0.1 * (points[:, 1] + 2), atol=1e-5)


def test_heightfield_visual_is_a_mesh_the_cameras_draw() -> None:
    """The heightmap's visual reaches PyBullet as a mesh file, which the OpenGL renderer tessellates
    into the grid's 32 triangles, 0.2 to 2.64 m up (TinyRenderer draws PyBullet's mesh itself)."""
    world = load_world(FIXTURES / "heightmap.sdf")
    physics = Physics(world)
    body = physics.add_model(world.model("terrain"))
    visuals = pb.getVisualShapeData(body.id, physicsClientId=physics.client)
    files = [Path(v[4].decode()) for v in visuals if v[2] == pb.GEOM_MESH]
    assert len(files) == 1
    positions = np.concatenate([part.positions for part in submeshes(str(files[0]))])
    physics.close()  # removes the generated files
    assert positions.shape == (32 * 3, 3)
    assert positions[:, 2].min() == pytest.approx(0.2) and positions[:, 2].max() == pytest.approx(
        0.2 + 2.44
    )  # grey 244 of 255 over 2.55 m


def test_nested_links_and_joints_by_scoped_name() -> None:
    """The nested fixture loads into PyBullet; the finger's tip is where the frame graph put it."""
    physics = Physics(load_world(asset("worlds/empty.sdf")))
    physics.add_model(load_model(FIXTURES / "nested.sdf"))
    body = physics.body("arm")
    assert set(body.joints) == {"wrist", "hand::knuckle"}
    (x, y, z), _ = physics.frame_pose("arm", "hand::finger::tip")
    physics.close()
    assert (x, y, z) == pytest.approx((1.0, 0.5, 0.2), abs=1e-6)
