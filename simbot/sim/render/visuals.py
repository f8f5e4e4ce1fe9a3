"""Each body's visuals as the pieces a renderer shades (`surfaces.py`), read from the body's URDF.

The URDF is the one the server wrote (description/urdf_writer.py): each `<visual>` has its origin,
geometry and URDF `<material>` (a colour, a texture, or a name of a robot-level material), and an
`<sdf_material>` beside it with the rest of the SDF material. PyBullet is asked only which index
each link has. A mesh file gives one piece per material it holds, unless the visual has a
material of its own, which replaces them all (as in Gazebo). A texture that cannot be read is a
warning and the visual keeps its colour.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from typing import Any

import numpy as np

from simbot.description.kinematics import urdf_origin
from simbot.description.resources import resolve
from simbot.sim.render.labels import pack
from simbot.sim.render.mesh_materials import pbr_specular, readable_image, scaled, submeshes
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.shapes import (
    GEOM_BOX,
    GEOM_CAPSULE,
    GEOM_CYLINDER,
    GEOM_PLANE,
    GEOM_SPHERE,
    Tessellated,
    primitive,
)
from simbot.sim.render.surfaces import RGB, Piece, Surface
from simbot.transform import matmul

UNCOLOURED = Surface(diffuse=(1.0, 1.0, 1.0), ambient=(1.0, 1.0, 1.0))
"""A visual without any material: white, as PyBullet draws it."""


def body_pieces(scene: BulletScene, name: str) -> list[Piece]:
    """The body's visuals in their URDF link frames, one piece per material, each with its
    visual's label and temperature (`SceneBody.annotated`)."""
    body = scene.bodies[name]
    robot = ET.fromstring(body.urdf)
    materials = {m.get("name", ""): m for m in robot.findall("material")}
    indices = link_indices(scene, name)
    pieces = []
    for link in robot.findall("link"):
        link_name = link.get("name", "")
        for visual in link.findall("visual"):
            label, temperature = body.annotated(link_name, visual.get("name", ""))
            annotated: dict[str, Any] = {
                "label": pack(label, body.instance),
                "temperature": math.nan if temperature is None else temperature,
            }
            pieces += [replace(p, **annotated) for p in _visual_pieces(indices[link_name], visual, materials)]
    return pieces


def link_indices(scene: BulletScene, name: str) -> dict[str, int]:
    """Each URDF link's PyBullet index (-1 the base)."""
    pb, client, body = scene.pb, scene.client, scene.ids[name]
    indices = {pb.getBodyInfo(body, physicsClientId=client)[0].decode(): -1}
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        indices[pb.getJointInfo(body, j, physicsClientId=client)[12].decode()] = j
    return indices


def visual_points(visual: ET.Element) -> np.ndarray:
    """The vertices a URDF visual is drawn with, in its link's frame (N×3): what a bounding box of
    it is fitted to (simbot/sim/render/boxes.py)."""
    pieces = _visual_pieces(-1, visual, {})
    return np.concatenate([p.positions for p in pieces]) if pieces else np.zeros((0, 3), np.float32)


def _visual_pieces(link: int, visual: ET.Element, materials: dict[str, ET.Element]) -> list[Piece]:
    origin = urdf_origin(visual).matrix()
    surface = _surface(visual, materials)
    shape = visual.find("geometry/*")
    if shape is None:
        return []
    if shape.tag == "mesh":
        original = visual.find("sdf_material[@mesh]")
        filename = shape.get("filename", "") if original is None else original.get("mesh", "")
        parts = _mesh_parts(filename, _numbers(shape.get("scale"), (1.0, 1.0, 1.0)))
        return [_piece(link, origin, part, surface or own or UNCOLOURED) for part, own in parts]
    tessellated = primitive(_GEOMETRY.get(shape.tag, -1), _dimensions(shape))
    return [] if tessellated is None else [_piece(link, origin, tessellated, surface or UNCOLOURED)]


def _piece(link: int, origin: np.ndarray, tessellated: Tessellated, surface: Surface) -> Piece:
    positions, normals, uvs = tessellated
    rotation = origin[:3, :3]
    placed = matmul(positions, rotation.T) + origin[:3, 3]
    return Piece(
        link, placed.astype(np.float32), matmul(normals, rotation.T).astype(np.float32), uvs.astype(np.float32), surface
    )


def _numbers(text: str | None, default: tuple[float, ...]) -> tuple[float, ...]:
    return default if text is None else tuple(float(word) for word in text.split())


_GEOMETRY = {
    "box": GEOM_BOX,
    "sphere": GEOM_SPHERE,
    "cylinder": GEOM_CYLINDER,
    "capsule": GEOM_CAPSULE,
    "plane": GEOM_PLANE,
}


def _dimensions(shape: ET.Element) -> tuple[float, ...]:
    """The sizes as `shapes.primitive` takes them (PyBullet's order: length before radius)."""
    if shape.tag == "box":
        return _numbers(shape.get("size"), (1.0, 1.0, 1.0))
    radius = float(shape.get("radius", "1"))
    return (radius,) if shape.tag == "sphere" else (float(shape.get("length", "1")), radius)


def _mesh_parts(filename: str, scale: tuple[float, ...]) -> list[tuple[Tessellated, Surface | None]]:
    """The mesh file's submeshes, scaled as the visual says, each with its own material."""
    path = resolve(filename).path
    if path is None:
        return []
    return [((*scaled(p.positions, p.normals, scale), p.uvs), p.surface) for p in submeshes(str(path))]


def _surface(visual: ET.Element, materials: dict[str, ET.Element]) -> Surface | None:
    """The visual's own material (URDF `<material>` and `<sdf_material>`), None when it has none."""
    material = visual.find("material")
    if material is not None and material.find("color") is None and material.find("texture") is None:
        material = materials.get(material.get("name", ""), material)  # a robot-level material named here
    sdf = visual.find("sdf_material")
    attrs = {} if sdf is None else {key: value for key, value in sdf.attrib.items() if key != "mesh"}
    if material is None and not attrs:
        return None
    color = _numbers(None if material is None else _attr(material, "color", "rgba"), (1.0, 1.0, 1.0, 1.0))
    diffuse = _numbers(attrs.get("diffuse") or attrs.get("ambient"), color)
    ambient = _numbers(attrs.get("ambient") or attrs.get("diffuse"), color)
    specular, shininess = _specular(attrs, _rgb(diffuse))
    return Surface(
        diffuse=_rgb(diffuse),
        ambient=_rgb(ambient),
        specular=specular,
        shininess=shininess,
        emissive=_rgb(_numbers(attrs.get("emissive"), (0.0, 0.0, 0.0))),
        opacity=(1.0 - float(attrs.get("transparency", "0"))) * (diffuse[3] if len(diffuse) > 3 else 1.0),
        lit=attrs.get("lighting", "true") != "false",
        albedo_map=_image(None if material is None else _attr(material, "texture", "filename")),
        normal_map=_image(attrs.get("normal_map")),
        cast_shadows=attrs.get("cast_shadows", "true") != "false",
    )


def _specular(attrs: dict[str, str], diffuse: RGB) -> tuple[RGB, float]:
    """SDF's `<specular>` and `<shininess>` where written; else what PBR's metalness and roughness
    stand for; else none."""
    pbr = pbr_specular(diffuse, float(attrs.get("metalness", "0")), float(attrs.get("roughness", "1")))
    written = attrs.get("specular")
    specular = _rgb(_numbers(written, (0.0, 0.0, 0.0))) if written or "roughness" not in attrs else pbr[0]
    shininess = float(attrs["shininess"]) if float(attrs.get("shininess", "0")) > 0 else None
    return specular, shininess or (pbr[1] if "roughness" in attrs else Surface.shininess)


def _attr(element: ET.Element, child: str, name: str) -> str | None:
    found = element.find(child)
    return None if found is None else found.get(name)


def _image(filename: str | None) -> str | None:
    """The texture's path where it resolves and decodes (a warning names it where not)."""
    if not filename:
        return None
    path = resolve(filename).path
    found = filename if path is None else str(path)
    return found if readable_image(found) else None


def _rgb(values: tuple[float, ...]) -> RGB:
    return (values[0], values[1], values[2])
