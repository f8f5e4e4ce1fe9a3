"""The visuals the render workers draw, as typed data (`urdf_visuals`, `SceneBody.visuals`): each
one exactly where, and what, the body's URDF draws (same link, same origin to the last bit, same
shape; a mesh PyBullet cannot read is its own file), picklable across the process boundary, and a
file that cannot be read is one warning naming it while the rest is drawn."""

from __future__ import annotations

import logging
import pickle
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
import trimesh
from conftest import REPO, ROBOT_SDF, TROLLEY_SDF

from simbot.description import load_model, load_world, model_to_urdf
from simbot.description.kinematics import urdf_origin
from simbot.description.model import Box, Capsule, Cylinder, Geometry, Link, Material, Mesh, Model, Sphere, Visual
from simbot.description.poses import Pose
from simbot.description.urdf_reader import load_urdf_model
from simbot.description.urdf_visuals import UrdfVisual, urdf_visuals
from simbot.description.urdf_writer import joint_trees
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.physics import Physics
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.specs import SceneBody
from simbot.sim.render.visuals import body_pieces
from simbot.transform import Transform

GAZEBO = REPO / "tests" / "fixtures" / "gazebo"


def _models() -> list[Model]:
    """The robot (links framed at their sensors, ball joints), the trolley, every SDF shape
    (planes, capsules, generated meshes), a heightmap, a model of two joint trees, a URDF robot."""
    worlds = [load_world(GAZEBO / name) for name in ("shapes.sdf", "heightmap.sdf", "two_trees.sdf")]
    models = [load_model(ROBOT_SDF), load_model(TROLLEY_SDF), *(m for w in worlds for m in w.models)]
    models.append(load_urdf_model(REPO / "tests" / "fixtures" / "two_wheels.urdf.xacro"))
    return [model for model in models if any(link.visuals for link in model.links)]


def _drawn_by_urdf(urdf: str) -> list[tuple[str, str, Pose, ET.Element, str | None]]:
    """Each `<visual>` of the URDF text: its link, name, origin, geometry and original mesh file."""
    robot = ET.fromstring(urdf)
    out = []
    for link in robot.findall("link"):
        for visual in link.findall("visual"):
            original = visual.find("sdf_material[@mesh]")
            shape = visual.find("geometry/*")
            assert shape is not None
            mesh = None if original is None else original.get("mesh")
            out.append((link.get("name", ""), visual.get("name", ""), urdf_origin(visual), shape, mesh))
    return out


def _numbers(shape: ET.Element, name: str) -> tuple[float, ...]:
    return tuple(float(word) for word in shape.get(name, "1 1 1").split())


def _same_shape(geometry: Geometry, shape: ET.Element, original: str | None) -> bool:
    if isinstance(geometry, Box):
        return shape.tag == "box" and geometry.size == _numbers(shape, "size")
    if isinstance(geometry, Sphere):
        return shape.tag == "sphere" and (geometry.radius,) == _numbers(shape, "radius")
    if isinstance(geometry, Cylinder | Capsule):
        sizes = _numbers(shape, "length") + _numbers(shape, "radius")
        return shape.tag == type(geometry).__name__.lower() and (geometry.length, geometry.radius) == sizes
    assert isinstance(geometry, Mesh) and geometry.path is not None, geometry
    file = original or shape.get("filename")
    return shape.tag == "mesh" and str(geometry.path.resolve()) == file and geometry.scale == _numbers(shape, "scale")


@pytest.mark.parametrize("model", [pytest.param(m, id=m.name) for m in _models()])
def test_each_visual_is_where_and_what_the_urdf_draws(model: Model, caplog: pytest.LogCaptureFixture) -> None:
    """In the URDF's order, on the same link, with the origin the URDF states (the same floats, so
    the same triangles), the same shape: a plane the URDF's box, a generated shape its OBJ."""
    caplog.set_level(logging.ERROR)
    checked = 0
    for tree in joint_trees(model):
        typed, written = urdf_visuals(tree), _drawn_by_urdf(model_to_urdf(tree))
        assert len(typed) == len(written)
        for drawn, (link, name, origin, shape, original) in zip(typed, written, strict=True):
            assert (drawn.link, drawn.visual.name) == (link, name)
            assert drawn.visual.pose == origin, f"{link}/{name}: {drawn.visual.pose} against {origin}"
            assert _same_shape(drawn.visual.geometry, shape, original), f"{link}/{name}: {drawn.visual.geometry}"
            checked += 1
    assert checked


def test_a_mesh_pybullet_cannot_read_is_its_own_file_with_its_material(tmp_path: Path) -> None:
    """A GLB: the URDF names an OBJ stand-in for PyBullet; the typed visual keeps the GLB itself
    and the description's material, and crosses the process boundary whole (pickled)."""
    glb = tmp_path / "crate.glb"
    trimesh.creation.box((1.0, 2.0, 3.0)).export(glb)
    material = Material(diffuse=(0.1, 0.2, 0.3, 1.0), roughness=0.4)
    visual = Visual("crate", Mesh("crate.glb", (2.0, 2.0, 2.0), glb), Pose((1.0, 0.0, 0.0)), material, 0.25)
    model = Model("crate", links=(Link("base", visuals=(visual,)),))
    visuals = urdf_visuals(model, tmp_path)
    assert visuals == (UrdfVisual("base", visual),)
    urdf = model_to_urdf(model, generated_dir=tmp_path)
    mesh = ET.fromstring(urdf).find(".//mesh")
    assert mesh is not None and mesh.get("filename", "").endswith(".obj")
    body = SceneBody("crate", urdf, True, Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), visuals=visuals)
    assert pickle.loads(pickle.dumps(body)) == body


def test_the_server_sends_each_body_with_its_visuals(caplog: pytest.LogCaptureFixture) -> None:
    """`scene_body`: the URDF the physics loaded and the visuals of its model, for every body."""
    caplog.set_level(logging.ERROR)
    description = load_world(GAZEBO / "two_trees.sdf")
    physics = Physics(description)
    try:
        for model in description.models:
            physics.add_model(model)
        for name in physics.body_names():
            body = scene_body(physics, name, instance=7)
            assert body.urdf == physics.urdf_of(name) and body.instance == 7
            assert body.visuals == urdf_visuals(physics.model_of(name))
            assert body.static == physics.model_of(name).static
    finally:
        physics.close()


def test_an_unreadable_mesh_and_a_corrupt_texture_are_one_warning_each_and_the_rest_is_drawn(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A box whose texture is a broken PNG keeps its colour; a mesh file of garbage is not drawn;
    a sphere beside them is: one warning naming each file, however often the body is read."""
    (tmp_path / "broken.png").write_bytes(b"\x89PNG broken")
    (tmp_path / "garbage.obj").write_bytes(b"\x00\x01 not a mesh \xff" * 10)
    textured = Material(diffuse=(1.0, 0.0, 0.0, 1.0), albedo_map=tmp_path / "broken.png")
    visuals = (
        Visual("box", Box((1.0, 1.0, 1.0)), material=textured),
        Visual("mesh", Mesh("garbage.obj", path=tmp_path / "garbage.obj")),
        Visual("sphere", Sphere(0.5), Pose((0.0, 2.0, 0.0))),
    )
    model = Model("thing", links=(Link("base", visuals=visuals),))
    body = SceneBody(
        "thing", model_to_urdf(model), True, Transform((0, 0, 0), (0, 0, 0, 1)), visuals=urdf_visuals(model)
    )
    scene = BulletScene(pb, [body])
    try:
        with caplog.at_level(logging.WARNING):
            box, sphere = body_pieces(scene, "thing")
            body_pieces(scene, "thing")
    finally:
        scene.close()
    assert box.surface.albedo_map is None and box.surface.diffuse == (1.0, 0.0, 0.0)
    assert np.allclose(sphere.positions.mean(axis=0), (0.0, 2.0, 0.0), atol=1e-6)
    for file in ("broken.png", "garbage.obj"):
        named = [r for r in caplog.records if r.levelno == logging.WARNING and str(tmp_path / file) in r.getMessage()]
        assert len(named) == 1, (file, [r.getMessage() for r in caplog.records])
