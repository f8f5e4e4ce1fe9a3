"""SDF as Gazebo reads it: loose XML, nested models, every shape, and Fuel URLs from the local cache.

The worlds are simbot's own, in tests/fixtures/gazebo, each a few lines reproducing one construct.
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from simbot.description import DescriptionError, load_model, load_world, model_to_urdf
from simbot.description.generated_meshes import cone, ellipsoid, heightmap, polyline
from simbot.description.model import Capsule, Cone, Ellipsoid, Heightmap, Mesh, Polyline, Sphere

FIXTURES = Path(__file__).parent / "fixtures" / "gazebo"


def test_comments_prefixes_and_scoped_names_are_read(caplog: pytest.LogCaptureFixture) -> None:
    """`--` in a comment, `gz:` / `experimental:` prefixes never declared, and `<gz::system_priority>`:
    the world loads, a plugin keeps the scoped parameter by its name, and a debug line says what was eased."""
    with caplog.at_level(logging.DEBUG, logger="simbot.description.xml"):
        world = load_world(FIXTURES / "tolerant.sdf")
    physics = next(p for p in world.plugins if p.name == "gz::sim::systems::Physics")
    assert physics.get("gz::system_priority") == "-10"
    assert world.model("box").link("link").collisions[0].geometry.size == (1.0, 1.0, 1.0)  # type: ignore[union-attr]
    logged = caplog.text
    assert "'--'" in logged and "experimental, gz" in logged and "'::'" in logged


def test_broken_xml_still_names_its_line(tmp_path: Path) -> None:
    """Easing Gazebo's quirks keeps line numbers: an unclosed element after a `--` comment is reported on its own line."""
    bad = tmp_path / "bad.sdf"
    bad.write_text("<sdf version='1.9'>\n<!-- a\n -- b -->\n<gz:x>\n<model name='m'>\n</sdf>")
    with pytest.raises(DescriptionError) as error:
        load_world(bad)
    assert f"{bad}:6:" in str(error.value) and "malformed XML" in str(error.value)


def test_nested_models_are_flattened_with_scoped_names() -> None:
    """A nested hand (yawed 90° at x 1) whose palm sits 0.5 along the hand's x, a finger nested in it
    0.2 above the palm; the arm's joint names `hand::palm`, the hand's names its nested `finger`."""
    model = load_model(FIXTURES / "nested.sdf")
    assert [link.name for link in model.links] == ["base", "hand::palm", "hand::finger::tip"]
    assert np.allclose(model.link("hand::palm").pose.xyz, (1.0, 0.5, 0.0))
    assert model.link("hand::palm").pose.rpy[2] == pytest.approx(math.pi / 2)
    assert np.allclose(model.link("hand::finger::tip").pose.xyz, (1.0, 0.5, 0.2))
    wrist, knuckle = model.joint("wrist"), model.joint("hand::knuckle")
    assert (wrist.parent, wrist.child) == ("base", "hand::palm")
    assert (knuckle.parent, knuckle.child) == ("hand::palm", "hand::finger::tip")
    assert np.allclose(knuckle.pose.xyz, (1.0, 0.5, 0.2))  # on its child, the nested model's frame


def test_nested_model_urdf_keeps_the_scoped_names() -> None:
    """The URDF names links and joints as the model does, so the simulator finds them by those names."""
    robot = ET.fromstring(model_to_urdf(load_model(FIXTURES / "nested.sdf")))
    assert {link.get("name") for link in robot.iter("link")} >= {"base", "hand::palm", "hand::finger::tip"}
    assert {joint.get("name") for joint in robot.iter("joint")} >= {"wrist", "hand::knuckle"}


def test_each_shape_is_read_with_sdf_defaults() -> None:
    """Capsule, ellipsoid, cone and polyline with their sizes; a `<sphere/>` takes SDF's radius of 1."""
    world = load_world(FIXTURES / "shapes.sdf")
    shapes = {m.name: m.links[0].collisions[0].geometry for m in world.models}
    assert shapes["capsule"] == Capsule(0.1, 0.4)
    assert shapes["ellipsoid"] == Ellipsoid((0.3, 0.2, 0.1))
    assert shapes["cone"] == Cone(0.2, 0.3)
    assert shapes["ball"] == Sphere(1.0)
    notch = shapes["notch"]
    assert isinstance(notch, Polyline) and notch.heights == (0.3,) and len(notch.outlines[0]) == 5


def test_generated_meshes_have_the_shapes_extent() -> None:
    """The meshes reach each shape's extremes exactly (vertices at poles, apex and rim) and close up:
    each is watertight, so its volume approaches the solid's as the facets get finer."""
    import trimesh

    cases = [
        (ellipsoid(Ellipsoid((0.3, 0.2, 0.1))), (0.3, 0.2, 0.1), 4 / 3 * math.pi * 0.3 * 0.2 * 0.1),
        (cone(Cone(0.2, 0.3)), (0.2, 0.2, 0.15), math.pi * 0.2**2 * 0.3 / 3),
    ]
    for (vertices, faces), half, volume in cases:
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        assert mesh.is_watertight and mesh.volume > 0  # outward faces
        assert np.allclose(vertices.max(axis=0)[[0, 2]], np.asarray(half)[[0, 2]])
        assert mesh.volume == pytest.approx(volume, rel=0.03)  # 32 facets: cos(π/32)² of the area
    vertices, faces = polyline(Polyline((((-0.5, -0.5), (0.5, -0.5), (0.0, 0.0), (0.5, 0.5), (-0.5, 0.5)),), (0.3,)))
    notch = trimesh.Trimesh(vertices, faces, process=False)
    assert notch.is_watertight and notch.volume == pytest.approx((1.0 - 0.25) * 0.3)  # the square less its notch


def test_heightmap_mesh_follows_the_image() -> None:
    """The ramp image's surface is z = 0.51 (x + 2) + 0.1 (y + 2) + pos z: row 0 is +y, column 0 is −x."""
    terrain = load_world(FIXTURES / "heightmap.sdf").model("terrain").links[0]
    shape = terrain.visuals[0].geometry
    assert isinstance(shape, Heightmap) and shape.path == FIXTURES / "ramp.png"
    vertices, faces = heightmap(shape)
    expected = 0.51 * (vertices[:, 0] + 2) + 0.1 * (vertices[:, 1] + 2) + 0.2
    assert len(vertices) == 25 and len(faces) == 32 and np.allclose(vertices[:, 2], expected)


def test_urdf_of_the_shapes(tmp_path: Path) -> None:
    """A capsule stays a capsule; the others become OBJ meshes beside the URDF; a static polyline
    collides concave; a heightmap keeps its visual mesh and leaves its collision to the simulator."""
    world = load_world(FIXTURES / "shapes.sdf")
    capsule = ET.fromstring(model_to_urdf(world.model("capsule"), tmp_path)).find("link/collision/geometry/capsule")
    assert capsule is not None and capsule.attrib == {"radius": "0.1", "length": "0.4"}
    for name in ("ellipsoid", "cone"):
        mesh = ET.fromstring(model_to_urdf(world.model(name), tmp_path)).find("link/collision/geometry/mesh")
        assert mesh is not None and (tmp_path / mesh.get("filename", "")).is_file()
    notch = ET.fromstring(model_to_urdf(world.model("notch"), tmp_path)).find("link/collision")
    assert notch is not None and notch.get("concave") == "yes"
    terrain = ET.fromstring(model_to_urdf(load_world(FIXTURES / "heightmap.sdf").model("terrain"), tmp_path)).find(
        "link"
    )
    assert (
        terrain is not None and terrain.find("collision") is None and terrain.find("visual/geometry/mesh") is not None
    )


def _fuel_world(tmp_path: Path, url: str) -> Path:
    world = tmp_path / "world.sdf"
    world.write_text(f"<sdf version='1.9'><world name='w'>\n<include><uri>{url}</uri></include></world></sdf>")
    return world


def _cache_model(cache: Path, version: int, size: float) -> None:
    """A model in the Fuel cache as Gazebo lays it out: host/owner/models/name/version, lower case."""
    folder = cache / "fuel.gazebosim.org" / "openrobotics" / "models" / "coke can" / str(version)
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "can.stl").write_text("solid can\nendsolid can\n")
    (folder / "model.config").write_text("<model><sdf version='1.9'>model.sdf</sdf></model>")
    (folder / "model.sdf").write_text(
        f"<sdf version='1.9'><model name='coke_can'><link name='l'><collision name='c'><geometry><box><size>{size} 1 1</size></box></geometry></collision>"
        "<visual name='v'><geometry><mesh><uri>meshes/can.stl</uri></mesh></geometry></visual></link></model></sdf>"
    )


def test_fuel_url_resolves_from_the_local_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a version the newest cached one; with a version that one; spelling as on the Fuel server."""
    cache = tmp_path / "fuel"
    _cache_model(cache, 1, 0.1)
    _cache_model(cache, 2, 0.2)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(cache))
    base = "https://fuel.gazebosim.org/1.0/OpenRobotics/models/Coke%20Can"
    for url, size in ((base, 0.2), (base + "/1", 0.1), (base + "/tip", 0.2)):
        link = load_world(_fuel_world(tmp_path, url)).model("coke_can").links[0]
        assert link.collisions[0].geometry.size[0] == size  # type: ignore[union-attr]
        visual = link.visuals[0].geometry
        assert isinstance(visual, Mesh) and visual.path is not None and visual.path.is_file()


def test_fuel_url_not_cached_says_simbot_downloads_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The one-line error names the URL, the cache folder looked in, and that nothing is downloaded."""
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "empty"))
    world = _fuel_world(tmp_path, "https://fuel.gazebosim.org/1.0/OpenRobotics/models/Pallet")
    with pytest.raises(DescriptionError) as error:
        load_world(world)
    message = str(error.value)
    assert f"{world}:2:" in message and "simbot downloads nothing" in message
    assert str(tmp_path / "empty" / "fuel.gazebosim.org" / "openrobotics" / "models" / "pallet") in message
