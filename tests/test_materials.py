"""Materials and textures from the SDF, URDF or mesh file to the pieces a renderer shades.

Each world is written into tmp_path with its assets (OBJ/MTL and PNG by hand, COLLADA as text,
GLB through trimesh), loaded by the server's physics, and its body as a render worker gets it
(`bodies.scene_body`: the URDF and the model's visuals as typed data) loaded into a render worker's
`BulletScene`: `body_pieces` must give each visual's, and each submesh's, surface, colours, texture
coordinates and texture file."""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import pybullet as pb
import pytest
import trimesh
import yourdfpy

from simbot.description import load_world
from simbot.description.model import World
from simbot.description.urdf_reader import load_urdf_model
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.physics import Physics
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.shapes import GEOM_MESH, primitive
from simbot.sim.render.surfaces import Piece
from simbot.sim.render.visuals import body_pieces
from simbot.transform import Transform

PiecesOf = Callable[[Path], list[Piece]]
RED, BLUE, GREEN = (0, 0, 255), (255, 0, 0), (0, 255, 0)
"""OpenCV's BGR."""


def write_image(path: Path, left: tuple[int, int, int], right: tuple[int, int, int]) -> npt.NDArray[np.uint8]:
    """An 8×8 PNG, its left half one colour, its right half another."""
    image = np.zeros((8, 8, 3), np.uint8)
    image[:, :4], image[:, 4:] = left, right
    assert cv2.imwrite(str(path), image)
    return image


def read_image(path: str) -> npt.NDArray[Any]:
    """The image OpenCV reads back from `path` (BGR), which must be there."""
    image = cv2.imread(path)
    assert image is not None, f"OpenCV cannot read {path}"
    return image


def world(tmp_path: Path, visuals: str, links: str = "") -> Path:
    """A world of one static model `thing` whose link `base` holds `visuals`, and `links` after it."""
    path = tmp_path / "world.sdf"
    path.write_text(
        '<?xml version="1.0"?>\n<sdf version="1.9"><world name="w"><model name="thing"><static>true</static>'
        f'<link name="base">{visuals}</link>{links}</model></world></sdf>\n'
    )
    return path


@pytest.fixture
def pieces_of() -> Iterator[PiecesOf]:
    """Loads a world file as the server does and gives `body_pieces` of its model `thing`."""
    opened: list[tuple[Physics, BulletScene]] = []

    def pieces(path: Path) -> list[Piece]:
        description = load_world(path)
        physics = Physics(description)
        scene = BulletScene(pb)
        opened.append((physics, scene))
        for model in description.models:
            physics.add_model(model)
        scene.add(scene_body(physics, "thing"))
        return body_pieces(scene, "thing")

    yield pieces
    for physics, scene in opened:
        scene.close()
        physics.close()


def box_visual(name: str, material: str = "", extra: str = "", pose: str = "0 0 0 0 0 0") -> str:
    return (
        f'<visual name="{name}"><pose>{pose}</pose><geometry><box><size>1 2 3</size></box></geometry>'
        f"{material}{extra}</visual>"
    )


# ---------------------------------------------------------------- SDF materials on primitives


FULL_MATERIAL = """<material>
  <ambient>0.2 0.3 0.4 1</ambient><diffuse>0.9 0.8 0.7 0.5</diffuse><specular>0.5 0.6 0.7 1</specular>
  <emissive>0 0.1 0 1</emissive><lighting>false</lighting><shininess>12</shininess>
  <pbr><metal><albedo_map>albedo.png</albedo_map><normal_map>normal.png</normal_map>
    <metalness>0.2</metalness><roughness>0.3</roughness></metal></pbr>
</material>"""


def test_sdf_material_is_read_whole(tmp_path: Path) -> None:
    write_image(tmp_path / "albedo.png", RED, BLUE)
    write_image(tmp_path / "normal.png", (255, 128, 128), (255, 128, 128))
    path = world(
        tmp_path,
        box_visual("panel", FULL_MATERIAL, "<transparency>0.25</transparency><cast_shadows>false</cast_shadows>"),
    )
    visual = load_world(path).model("thing").link("base").visuals[0]
    material = visual.material
    assert material is not None
    assert (material.ambient, material.diffuse) == ((0.2, 0.3, 0.4, 1.0), (0.9, 0.8, 0.7, 0.5))
    assert (material.specular, material.emissive) == ((0.5, 0.6, 0.7, 1.0), (0.0, 0.1, 0.0, 1.0))
    assert (material.lighting, material.shininess, material.metalness, material.roughness) == (False, 12.0, 0.2, 0.3)
    assert material.albedo_map == tmp_path / "albedo.png" and material.normal_map == tmp_path / "normal.png"
    assert (visual.transparency, visual.cast_shadows) == (0.25, False)


def test_pbr_specular_workflow_and_defaults(tmp_path: Path) -> None:
    """`<pbr><specular>`: glossiness is 1 − roughness, no metalness; a bare `<material>` is lit, casts shadows."""
    write_image(tmp_path / "albedo.png", RED, BLUE)
    pbr = "<material><pbr><specular><albedo_map>albedo.png</albedo_map><glossiness>0.8</glossiness></specular></pbr></material>"
    path = world(tmp_path, box_visual("a", pbr) + box_visual("b", "<material/>"))
    a, b = load_world(path).model("thing").link("base").visuals
    assert a.material is not None and a.material.roughness == pytest.approx(0.2) and a.material.metalness == 0.0
    assert a.material.albedo_map == tmp_path / "albedo.png"
    assert b.material is not None and b.material.lighting and b.material.albedo_map is None
    assert b.transparency == 0.0 and b.cast_shadows


def test_primitive_with_sdf_material_becomes_one_piece_with_its_surface(tmp_path: Path, pieces_of: PiecesOf) -> None:
    write_image(tmp_path / "albedo.png", RED, BLUE)
    write_image(tmp_path / "normal.png", (255, 128, 128), (255, 128, 128))
    extra = "<transparency>0.25</transparency><cast_shadows>false</cast_shadows>"
    [piece] = pieces_of(world(tmp_path, box_visual("panel", FULL_MATERIAL, extra, pose="1 2 3 0 0 0")))
    surface = piece.surface
    assert (surface.ambient, surface.diffuse, surface.specular) == ((0.2, 0.3, 0.4), (0.9, 0.8, 0.7), (0.5, 0.6, 0.7))
    assert (surface.emissive, surface.shininess, surface.lit, surface.cast_shadows) == (
        (0.0, 0.1, 0.0),
        12.0,
        False,
        False,
    )
    assert surface.opacity == pytest.approx(0.75 * 0.5)  # 1 − transparency, times the diffuse alpha
    assert surface.albedo_map == str(tmp_path / "albedo.png")
    assert surface.normal_map == str(tmp_path / "normal.png")
    assert piece.link == -1 and len(piece.positions) == 36
    assert np.allclose(piece.positions.min(axis=0), (0.5, 1.0, 1.5)) and np.allclose(
        piece.positions.max(axis=0), (1.5, 3.0, 4.5)
    )


def test_each_box_face_shows_the_whole_image_unmirrored(tmp_path: Path, pieces_of: PiecesOf) -> None:
    """Per face (six rows of one normal): u and v span 0..1, and u × v (in space) is the outward normal."""
    [piece] = pieces_of(world(tmp_path, box_visual("b")))
    for face in range(6):
        rows = slice(6 * face, 6 * face + 6)
        uv, position, normal = piece.uvs[rows], piece.positions[rows].astype(float), piece.normals[rows][0]
        assert np.allclose(uv.min(axis=0), 0.0) and np.allclose(uv.max(axis=0), 1.0)
        # the surface gradient of u and v from the face's first triangle
        edges = position[1:3] - position[0]
        duv = uv[1:3] - uv[0]
        gradients = np.linalg.lstsq(duv, edges, rcond=None)[0]  # rows: ∂p/∂u, ∂p/∂v
        assert np.dot(np.cross(gradients[0], gradients[1]), normal) > 0, f"face {face} is mirrored"


def test_round_shapes_wrap_the_image_once(tmp_path: Path, pieces_of: PiecesOf) -> None:
    visuals = "".join(
        f'<visual name="{n}"><geometry>{g}</geometry></visual>'
        for n, g in (
            ("cylinder", "<cylinder><radius>0.5</radius><length>1</length></cylinder>"),
            ("sphere", "<sphere><radius>0.5</radius></sphere>"),
            ("capsule", "<capsule><radius>0.5</radius><length>1</length></capsule>"),
        )
    )
    for piece in pieces_of(world(tmp_path, visuals)):
        assert np.allclose(piece.uvs.min(axis=0), 0.0) and np.allclose(piece.uvs.max(axis=0), 1.0)
        on_axis = np.hypot(piece.positions[:, 0], piece.positions[:, 1]) < 1e-6
        assert on_axis.any()
        top, bottom = piece.positions[:, 2].max(), piece.positions[:, 2].min()
        assert np.allclose(piece.uvs[on_axis & (piece.positions[:, 2] == top), 1], 1.0), "v is 1 at the top"
        assert np.allclose(piece.uvs[on_axis & (piece.positions[:, 2] == bottom), 1], 0.0), "v is 0 at the bottom"
        assert piece.surface.diffuse == (1.0, 1.0, 1.0)  # no material: white, as PyBullet draws it


def test_visuals_are_in_their_links_frames(tmp_path: Path, pieces_of: PiecesOf) -> None:
    """A second link placed 2 m up by its joint: its visual's piece is link 0, at its own origin."""
    arm = """<link name="arm"><pose>0 0 2 0 0 0</pose>
      <visual name="v"><geometry><sphere><radius>0.1</radius></sphere></geometry>
      <material><diffuse>0 1 0 1</diffuse></material></visual></link>
      <joint name="j" type="revolute"><parent>base</parent><child>arm</child><axis><xyz>0 0 1</xyz></axis></joint>"""
    base, arm_piece = pieces_of(world(tmp_path, box_visual("b"), arm))
    assert base.link == -1 and arm_piece.link == 0
    assert np.allclose(arm_piece.positions.mean(axis=0), 0.0, atol=1e-6)
    assert arm_piece.surface.diffuse == arm_piece.surface.ambient == (0.0, 1.0, 0.0)


def test_written_urdf_loads_in_pybullet_and_urdf_readers(tmp_path: Path) -> None:
    """The URDF with `<texture>` and `<sdf_material>`: PyBullet loads it (with the texture), yourdfpy
    (ROS's robot_description readers) and simbot's own URDF reader read it back."""
    write_image(tmp_path / "albedo.png", RED, BLUE)
    write_image(tmp_path / "normal.png", (255, 128, 128), (255, 128, 128))
    description = load_world(world(tmp_path, box_visual("panel", FULL_MATERIAL)))
    physics = Physics(description)
    try:
        physics.add_model(description.models[0])
        urdf = physics.urdf_of("thing")
    finally:
        physics.close()
    assert "<texture filename=" in urdf and "<sdf_material " in urdf
    file = tmp_path / "thing.urdf"
    file.write_text(urdf)
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(file), physicsClientId=client)
        [shape] = pb.getVisualShapeData(body, physicsClientId=client)
        assert shape[7] == pytest.approx((0.9, 0.8, 0.7, 0.5)), "PyBullet reads URDF's <color>"
    finally:
        pb.disconnect(client)
    visual = yourdfpy.URDF.load(str(file)).robot.links[0].visuals[0]
    assert visual.material is not None and visual.material.texture.filename == str(tmp_path / "albedo.png")
    read_back = load_urdf_model(file).link("base").visuals[0].material
    assert read_back is not None and read_back.color() == (0.9, 0.8, 0.7, 0.5)


# ---------------------------------------------------------------- mesh files


OBJ = """mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl plain
f 1/1 2/2 3/3
usemtl textured
f 1/1 3/3 4/4
"""
MTL = """newmtl plain
Kd 1 0 0
Ka 0.5 0 0
Ks 0.2 0.3 0.4
Ns 50
Ke 0 0 0.1
d 0.5
newmtl textured
Kd 1 1 1
map_Kd {texture}
"""


def write_obj(folder: Path, texture: str = "stripes.png") -> None:
    (folder / "m.obj").write_text(OBJ)
    (folder / "m.mtl").write_text(MTL.format(texture=texture))


def mesh_visual(uri: str, material: str = "", scale: str = "1 1 1") -> str:
    return (
        f'<visual name="m"><geometry><mesh><uri>{uri}</uri><scale>{scale}</scale></mesh></geometry>{material}</visual>'
    )


def by_colour(pieces: list[Piece]) -> dict[tuple[float, float, float], Piece]:
    return {p.surface.diffuse: p for p in pieces}


def test_obj_keeps_each_mtl_material_with_its_texture_and_uvs(tmp_path: Path, pieces_of: PiecesOf) -> None:
    image = write_image(tmp_path / "stripes.png", RED, BLUE)
    write_obj(tmp_path)
    pieces = by_colour(pieces_of(world(tmp_path, mesh_visual("m.obj", scale="2 2 2"))))
    plain, textured = pieces[(1.0, 0.0, 0.0)], pieces[(1.0, 1.0, 1.0)]
    assert (plain.surface.ambient, plain.surface.specular, plain.surface.emissive) == (
        (0.5, 0, 0),
        (0.2, 0.3, 0.4),
        (0, 0, 0.1),
    )
    assert (plain.surface.shininess, plain.surface.opacity, plain.surface.albedo_map) == (50.0, 0.5, None)
    assert textured.surface.albedo_map is not None
    assert np.array_equal(read_image(textured.surface.albedo_map), image), "the texture file holds the MTL's image"
    # the textured triangle 1 3 4: corners (0,0) (1,1) (0,1) scaled by 2, uvs as the vt's
    corners = {tuple(p): tuple(uv) for p, uv in zip(textured.positions.tolist(), textured.uvs.tolist(), strict=True)}
    assert corners == {(0.0, 0.0, 0.0): (0.0, 0.0), (2.0, 2.0, 0.0): (1.0, 1.0), (0.0, 2.0, 0.0): (0.0, 1.0)}
    assert np.allclose(textured.normals, (0.0, 0.0, 1.0))


def test_the_same_mesh_with_another_texture_shows_that_texture(tmp_path: Path, pieces_of: PiecesOf) -> None:
    """The texture cache is keyed by the image, not the mesh file (its MTL and image may change alone)."""
    images = []
    for folder, colours in (("a", (RED, BLUE)), ("b", (GREEN, RED))):
        (tmp_path / folder).mkdir()
        images.append(write_image(tmp_path / folder / "stripes.png", *colours))
        write_obj(tmp_path / folder)
    for folder, image in zip("ab", images, strict=True):
        textured = by_colour(pieces_of(world(tmp_path / folder, mesh_visual("m.obj"))))[(1.0, 1.0, 1.0)]
        assert textured.surface.albedo_map is not None
        assert np.array_equal(read_image(textured.surface.albedo_map), image), folder


def test_an_sdf_material_replaces_the_mesh_materials(tmp_path: Path, pieces_of: PiecesOf) -> None:
    write_image(tmp_path / "stripes.png", RED, BLUE)
    write_obj(tmp_path)
    pieces = pieces_of(world(tmp_path, mesh_visual("m.obj", "<material><diffuse>0 1 0 1</diffuse></material>")))
    assert len(pieces) == 2 and {p.surface.diffuse for p in pieces} == {(0.0, 1.0, 0.0)}
    assert all(p.surface.albedo_map is None for p in pieces)


def test_a_mirroring_scale_mirrors_the_normals(tmp_path: Path, pieces_of: PiecesOf) -> None:
    write_image(tmp_path / "stripes.png", RED, BLUE)
    write_obj(tmp_path)
    for piece in pieces_of(world(tmp_path, mesh_visual("m.obj", scale="1 1 -1"))):
        assert np.allclose(piece.normals, (0.0, 0.0, -1.0))


COLLADA = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_images><image id="img"><init_from>{texture}</init_from></image></library_images>
  <library_effects>
    <effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
      <emission><color>0 0 0.2 1</color></emission>
      <diffuse><color>1 0 0 1</color></diffuse>
      <shininess><float>20</float></shininess>
    </phong></technique></profile_COMMON></effect>
    <effect id="tex-fx"><profile_COMMON>
      <newparam sid="surf"><surface type="2D"><init_from>img</init_from></surface></newparam>
      <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
      <technique sid="common"><lambert><diffuse><texture texture="samp" texcoord="UVMap"/></diffuse></lambert></technique>
    </profile_COMMON></effect>
  </library_effects>
  <library_materials>
    <material id="red-mat" name="red"><instance_effect url="#red-fx"/></material>
    <material id="tex-mat" name="tex"><instance_effect url="#tex-fx"/></material>
  </library_materials>
  <library_geometries><geometry id="quad"><mesh>
    <source id="pos"><float_array id="pos-a" count="12">0 0 0 1 0 0 1 1 0 0 1 0</float_array>
      <technique_common><accessor source="#pos-a" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <source id="uv"><float_array id="uv-a" count="8">0 0 1 0 1 1 0 1</float_array>
      <technique_common><accessor source="#uv-a" count="4" stride="2">
        <param name="S" type="float"/><param name="T" type="float"/>
      </accessor></technique_common></source>
    <vertices id="vtx"><input semantic="POSITION" source="#pos"/></vertices>
    <triangles material="red-sym" count="1"><input semantic="VERTEX" source="#vtx" offset="0"/>
      <input semantic="TEXCOORD" source="#uv" offset="1" set="0"/><p>0 0 1 1 2 2</p></triangles>
    <triangles material="tex-sym" count="1"><input semantic="VERTEX" source="#vtx" offset="0"/>
      <input semantic="TEXCOORD" source="#uv" offset="1" set="0"/><p>0 0 2 2 3 3</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene"><node id="n" name="n">
    <matrix>1 0 0 0 0 1 0 0 0 0 1 2 0 0 0 1</matrix>
    <instance_geometry url="#quad"><bind_material><technique_common>
      <instance_material symbol="red-sym" target="#red-mat"/>
      <instance_material symbol="tex-sym" target="#tex-mat">
        <bind_vertex_input semantic="UVMap" input_semantic="TEXCOORD" input_set="0"/></instance_material>
    </technique_common></bind_material></instance_geometry>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""


def test_collada_keeps_each_material_and_its_node_transform(tmp_path: Path, pieces_of: PiecesOf) -> None:
    image = write_image(tmp_path / "blue.png", BLUE, GREEN)
    (tmp_path / "m.dae").write_text(COLLADA.format(texture="blue.png"))
    pieces = by_colour(pieces_of(world(tmp_path, mesh_visual("m.dae"))))
    red, textured = pieces[(1.0, 0.0, 0.0)], pieces[(1.0, 1.0, 1.0)]
    assert red.surface.emissive == pytest.approx((0.0, 0.0, 0.2)) and red.surface.albedo_map is None
    assert red.surface.shininess == pytest.approx(20.0)
    assert textured.surface.albedo_map is not None and np.array_equal(read_image(textured.surface.albedo_map), image)
    assert np.allclose(red.positions[:, 2], 2.0) and np.allclose(textured.positions[:, 2], 2.0), "the node's matrix"
    assert sorted(map(tuple, textured.uvs.tolist())) == [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0)]


def write_glb(path: Path) -> npt.NDArray[np.uint8]:
    """Two boxes: one textured, emissive, at the origin; one red, 5 m up by its node."""
    import trimesh
    from PIL import Image

    pixels = np.zeros((4, 4, 3), np.uint8)
    pixels[:] = (0, 255, 0)
    uv = np.tile([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], (2, 1))
    textured = trimesh.creation.box()
    textured.visual = trimesh.visual.TextureVisuals(
        uv=uv,
        material=trimesh.visual.material.PBRMaterial(
            baseColorFactor=[255, 255, 255, 255], baseColorTexture=Image.fromarray(pixels), emissiveFactor=[0.1, 0, 0]
        ),
    )
    red = trimesh.creation.box()
    red.visual = trimesh.visual.TextureVisuals(
        uv=uv, material=trimesh.visual.material.PBRMaterial(baseColorFactor=[255, 0, 0, 128])
    )
    scene = trimesh.Scene()
    scene.add_geometry(textured, node_name="textured")
    scene.add_geometry(red, node_name="red", transform=trimesh.transformations.translation_matrix([0, 0, 5]))
    path.write_bytes(scene.export(file_type="glb"))
    return pixels


def test_glb_keeps_base_colours_textures_emission_and_nodes(tmp_path: Path, pieces_of: PiecesOf) -> None:
    """PyBullet cannot read a GLB: it gets an OBJ stand-in (for the collision too), the renderer the file."""
    pixels = write_glb(tmp_path / "m.glb")
    collision = '<collision name="c"><geometry><mesh><uri>m.glb</uri></mesh></geometry></collision>'
    pieces = by_colour(pieces_of(world(tmp_path, mesh_visual("m.glb") + collision)))
    red, textured = pieces[(1.0, 0.0, 0.0)], pieces[(1.0, 1.0, 1.0)]
    assert red.surface.opacity == pytest.approx(128 / 255) and red.surface.albedo_map is None
    assert np.allclose(red.positions.mean(axis=0), (0.0, 0.0, 5.0)) and np.allclose(
        textured.positions.mean(axis=0), 0.0
    )
    assert textured.surface.emissive == pytest.approx((0.1, 0.0, 0.0))
    assert textured.surface.albedo_map is not None
    assert np.array_equal(read_image(textured.surface.albedo_map)[:, :, ::-1], pixels)
    assert len(textured.positions) == 36 and textured.uvs.max() == pytest.approx(1.0)


# ---------------------------------------------------------------- bad input


def warnings_naming(caplog: pytest.LogCaptureFixture, name: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and name in r.getMessage()]


def test_a_missing_pbr_map_warns_once_and_the_colour_stays(
    tmp_path: Path, pieces_of: PiecesOf, caplog: pytest.LogCaptureFixture
) -> None:
    material = (
        "<material><diffuse>0 0 1 1</diffuse><pbr><metal><albedo_map>nowhere.png</albedo_map></metal></pbr></material>"
    )
    [piece] = pieces_of(world(tmp_path, box_visual("b", material)))
    assert piece.surface.diffuse == (0.0, 0.0, 1.0) and piece.surface.albedo_map is None
    [message] = warnings_naming(caplog, "nowhere.png")
    assert "world.sdf" in message and "\n" not in message


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("bad.png", b"not an image at all"),
        ("bad.dds", b"DDS |" + bytes(124)),
        ("cut.png", b"\x89PNG\r\n\x1a\n" + bytes(64)),
    ],
    ids=["corrupt", "dds", "truncated-png"],
)
def test_an_unreadable_albedo_map_warns_once_and_the_colour_stays(
    tmp_path: Path, pieces_of: PiecesOf, caplog: pytest.LogCaptureFixture, name: str, content: bytes
) -> None:
    """Garbage, a format OpenCV does not decode (DDS): the SDF reader leaves the map out; a PNG
    whose header is right and the rest not: the render worker finds out. Two visuals, one warning."""
    (tmp_path / name).write_bytes(content)
    material = (
        f"<material><diffuse>0 0 1 1</diffuse><pbr><metal><albedo_map>{name}</albedo_map></metal></pbr></material>"
    )
    path = world(tmp_path, box_visual("a", material) + box_visual("b", material))
    pieces = pieces_of(path)
    assert [p.surface.albedo_map for p in pieces] == [None, None]
    assert {p.surface.diffuse for p in pieces} == {(0.0, 0.0, 1.0)}
    [message] = warnings_naming(caplog, str(tmp_path / name))
    assert "\n" not in message


def test_a_corrupt_mesh_texture_warns_once_and_the_material_colour_stays(
    tmp_path: Path, pieces_of: PiecesOf, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "stripes.png").write_bytes(b"\x89PNG broken")
    write_obj(tmp_path)
    pieces = by_colour(pieces_of(world(tmp_path, mesh_visual("m.obj"))))
    assert pieces[(1.0, 1.0, 1.0)].surface.albedo_map is None and pieces[(1.0, 0.0, 0.0)].surface.opacity == 0.5
    assert len(warnings_naming(caplog, str(tmp_path / "stripes.png"))) == 1


def test_a_missing_collada_texture_warns_and_its_material_keeps_its_colour(
    tmp_path: Path, pieces_of: PiecesOf, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "m.dae").write_text(COLLADA.format(texture="gone.png"))
    pieces = by_colour(pieces_of(world(tmp_path, mesh_visual("m.dae"))))
    assert set(pieces) == {(1.0, 0.0, 0.0), (1.0, 1.0, 1.0)}
    assert all(p.surface.albedo_map is None for p in pieces.values())
    assert len(warnings_naming(caplog, str(tmp_path / "gone.png"))) == 1


def test_a_missing_material_library_warns_and_the_mesh_is_drawn_without_it(
    tmp_path: Path, pieces_of: PiecesOf, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "m.obj").write_text(OBJ)
    pieces = pieces_of(world(tmp_path, mesh_visual("m.obj", "")))
    assert sum(len(p.positions) for p in pieces) == 6
    assert all(p.surface.albedo_map is None for p in pieces)
    [message] = warnings_naming(caplog, str(tmp_path / "m.mtl"))
    assert str(tmp_path / "m.obj") in message


# ---------------------------------------------------------------- the same visuals PyBullet loaded

EVERY_SHAPE_URDF = """<robot name="every">
  <material name="named"><color rgba="0.1 0.2 0.3 1"/></material>
  <link name="base">
    <visual><origin xyz="1 2 3" rpy="0.1 0.2 0.3"/><geometry><box size="0.4 0.6 0.8"/></geometry>
      <material name="named"/></visual>
  </link>
  <joint name="j" type="revolute"><origin xyz="0 0 1" rpy="0 0.5 0"/><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="arm">
    <visual><origin xyz="0.5 0 0"/><geometry><cylinder radius="0.25" length="0.8"/></geometry>
      <material name="g"><color rgba="0 1 0 1"/></material></visual>
    <visual><geometry><sphere radius="0.3"/></geometry></visual>
    <visual><origin xyz="0 0 -1"/><geometry><mesh filename="{mesh}" scale="0.001 -0.002 0.001"/></geometry>
      <material name="c"><color rgba="0 1 1 1"/></material></visual>
  </link>
</robot>"""


def rows(positions: npt.NDArray[np.floating[Any]]) -> npt.NDArray[np.float64]:
    """The vertices as a sorted set of rows (to 0.1 mm): the same triangles whatever their order."""
    return np.unique(np.round(positions.astype(np.float64), 4), axis=0)


def pybullet_view(scene: BulletScene, name: str) -> dict[int, tuple[npt.NDArray[np.float64], set[tuple[float, ...]]]]:
    """Per link: the vertices of PyBullet's visual shapes (getVisualShapeData, tessellated with the
    renderer's primitives, meshes read by trimesh alone) and their colours: the reference that
    body_pieces, which draws the description's visuals, must agree with."""
    links: dict[int, tuple[list[npt.NDArray[np.float64]], set[tuple[float, ...]]]] = {}
    for shape in scene.pb.getVisualShapeData(scene.ids[name], physicsClientId=scene.client):
        link, geometry, dimensions, mesh_file, position, orientation, rgba = shape[1:8]
        if geometry == GEOM_MESH:
            loaded = trimesh.load(mesh_file.decode(), force="mesh")
            assert isinstance(loaded, trimesh.Trimesh), mesh_file
            local = np.asarray(loaded.vertices)[np.asarray(loaded.faces)].reshape(-1, 3) * np.asarray(dimensions[:3])
        else:
            tessellated = primitive(geometry, tuple(dimensions))
            assert tessellated is not None, f"PyBullet geometry type {geometry}"
            local = tessellated[0]
        matrix = Transform.of(position, orientation).matrix()
        vertices, colours = links.setdefault(link, ([], set()))
        vertices.append(local @ matrix[:3, :3].T + matrix[:3, 3])
        colours.add(tuple(round(c, 4) for c in rgba[:3]))
    return {link: (rows(np.concatenate(p)), c) for link, (p, c) in links.items()}


def our_view(scene: BulletScene, name: str) -> dict[int, tuple[npt.NDArray[np.float64], set[tuple[float, ...]]]]:
    links: dict[int, tuple[list[npt.NDArray[np.float32]], set[tuple[float, ...]]]] = {}
    for piece in body_pieces(scene, name):
        positions, colours = links.setdefault(piece.link, ([], set()))
        positions.append(piece.positions)
        colours.add(tuple(round(c, 4) for c in piece.surface.diffuse))
    return {link: (rows(np.concatenate(p)), c) for link, (p, c) in links.items()}


def test_a_urdf_robot_gives_the_pieces_pybullet_loaded(tmp_path: Path) -> None:
    """A robot described by URDF alone (read into a model, as the server reads one): box, cylinder,
    sphere and a mirrored mesh over two links, and a material named at robot level: the same
    vertices per link as PyBullet's visual shapes, the same colours. (Planes and capsules, which
    URDF readers do not know, come from SDF: the next test.)"""
    from simbot.description.resources import asset

    (tmp_path / "every.urdf").write_text(EVERY_SHAPE_URDF.format(mesh=asset("meshes/wheel.stl")))
    physics = Physics(World("w"))
    scene = BulletScene(pb)
    try:
        physics.add_model(load_urdf_model(tmp_path / "every.urdf"))
        scene.add(scene_body(physics, "every"))
        ours, theirs = our_view(scene, "every"), pybullet_view(scene, "every")
    finally:
        scene.close()
        physics.close()
    assert ours.keys() == theirs.keys() == {-1, 0}
    for link in ours:
        assert np.array_equal(ours[link][0], theirs[link][0]), f"link {link}: other vertices"
        assert ours[link][1] == theirs[link][1], f"link {link}: other colours"


@pytest.mark.parametrize("world_file", ["tests/fixtures/gazebo/shapes.sdf", "worlds/warehouse.sdf"])
def test_sdf_worlds_give_the_pieces_pybullet_loaded(world_file: str) -> None:
    """Generated meshes (ellipsoid, cone, polyline), planes as boxes, the tug's meshes: nothing is
    lost or moved against what PyBullet loaded from the same URDF. A body with no visual at all
    shows nothing, as in Gazebo (PyBullet makes visuals of its collisions)."""
    from simbot.description.resources import asset

    description = load_world(asset(world_file) if world_file.startswith("worlds") else Path(world_file))
    physics = Physics(description)
    scene = BulletScene(pb)
    try:
        for model in description.models:
            physics.add_model(model)
        for name in physics.moving_bodies() + [m.name for m in description.models if m.static]:
            scene.add(scene_body(physics, name))
            if "<visual" not in physics.urdf_of(name):
                assert body_pieces(scene, name) == [], "Gazebo draws no collisions (PyBullet shows them)"
                continue
            ours, theirs = our_view(scene, name), pybullet_view(scene, name)
            assert ours.keys() == theirs.keys(), name
            for link in ours:
                assert np.array_equal(ours[link][0], theirs[link][0]), f"{name} link {link}: other vertices"
                assert ours[link][1] == theirs[link][1], f"{name} link {link}: other colours"
    finally:
        scene.close()
        physics.close()
