"""Each body's visuals as the pieces a renderer shades (`surfaces.py`), from the typed visuals the
server sent with the body (`SceneBody.visuals`: the description's, as its URDF places them).

PyBullet is asked only which index each URDF link has. A visual's material is the description's
(`Material`, with the visual's transparency and shadows); a primitive is tessellated as PyBullet
draws it. A mesh file gives one piece per material it holds, unless the visual has a material of
its own, which replaces them all (as in Gazebo). What cannot be read is one warning naming the
file, and the rest is drawn: a texture keeps its visual's colour, a mesh file is left out
(`mesh_materials.py`).
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from simbot.description.actor_scripts import SkinnedMesh
from simbot.description.model import RGBA, Box, Capsule, Cylinder, Geometry, Material, Mesh, Sphere, Visual
from simbot.description.skeleton_poses import Rig, load_rig
from simbot.description.skeletons import SkeletonError, SkinPart
from simbot.sim.render.label_bits import pack
from simbot.sim.render.mesh_materials import pbr_specular, readable_image, scaled, submeshes
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.shapes import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_SPHERE, Tessellated, primitive
from simbot.sim.render.skinning import Skinned
from simbot.sim.render.surfaces import RGB, Piece, Surface
from simbot.transform import matmul

log = logging.getLogger(__name__)
UNCOLOURED = Surface(diffuse=(1.0, 1.0, 1.0), ambient=(1.0, 1.0, 1.0))
"""A visual without any material: white, as PyBullet draws it."""
WHITE: RGBA = (1.0, 1.0, 1.0, 1.0)
BLACK: RGBA = (0.0, 0.0, 0.0, 1.0)


def body_pieces(scene: BulletScene, name: str) -> list[Piece]:
    """The body's visuals in their URDF link frames, one piece per material, each with its
    visual's label and temperature (`SceneBody.annotated`)."""
    body = scene.bodies[name]
    indices = link_indices(scene, name)
    pieces = []
    for drawn in body.visuals:
        label, temperature = body.annotated(drawn.link, drawn.visual.name)
        annotated: dict[str, Any] = {
            "label": pack(label, body.instance),
            "temperature": math.nan if temperature is None else temperature,
        }
        pieces += [replace(p, **annotated) for p in _visual_pieces(indices[drawn.link], drawn.visual)]
    return pieces


def link_indices(scene: BulletScene, name: str) -> dict[str, int]:
    """Each URDF link's PyBullet index (-1 the base)."""
    pb, client, body = scene.pb, scene.client, scene.ids[name]
    indices = {pb.getBodyInfo(body, physicsClientId=client)[0].decode(): -1}
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        indices[pb.getJointInfo(body, j, physicsClientId=client)[12].decode()] = j
    return indices


def visual_points(visual: Visual, joints: Mapping[str, float] | None = None) -> np.ndarray:
    """The vertices a visual is drawn with, in its link's frame (N×3): what a bounding box of it is
    fitted to (simbot/sim/render/boxes.py); a skin posed as `joints` say, where given."""
    pieces = _visual_pieces(-1, visual)
    points = [p.skin.posed(joints)[0] if p.skin is not None and joints is not None else p.positions for p in pieces]
    return np.concatenate(points) if points else np.zeros((0, 3), np.float32)


def _visual_pieces(link: int, visual: Visual) -> list[Piece]:
    origin = visual.pose.matrix()
    surface = _surface(visual)
    if isinstance(visual.geometry, SkinnedMesh) and (rig := _rig(visual.geometry)) is not None:
        scale = np.asarray(visual.geometry.scale[:3], dtype=np.float64)
        return [_skinned(link, origin, scale, rig, part, surface) for part in rig.skeleton.parts]
    if isinstance(visual.geometry, Mesh):
        parts = _mesh_parts(visual.geometry)
        return [_piece(link, origin, part, surface or own or UNCOLOURED) for part, own in parts]
    tessellated = _primitive(visual.geometry)
    return [] if tessellated is None else [_piece(link, origin, tessellated, surface or UNCOLOURED)]


def _piece(link: int, origin: np.ndarray, tessellated: Tessellated, surface: Surface) -> Piece:
    positions, normals, uvs = tessellated
    rotation = origin[:3, :3]
    placed = matmul(positions, rotation.T) + origin[:3, 3]
    return Piece(
        link, placed.astype(np.float32), matmul(normals, rotation.T).astype(np.float32), uvs.astype(np.float32), surface
    )


def _rig(mesh: SkinnedMesh) -> Rig | None:
    """The skin's rig; None (drawn as a plain mesh) where it cannot be read now, with a warning."""
    assert mesh.path is not None  # a SkinnedMesh is made only for a skin that was found
    try:
        return load_rig(mesh.path, mesh.animations)
    except SkeletonError as exc:
        log.warning("%s; it is drawn unanimated", exc)
        return None


def _skinned(link: int, origin: np.ndarray, scale: np.ndarray, rig: Rig, part: SkinPart, own: Surface | None) -> Piece:
    """A skinned part as a piece in its bind pose, flat-shaded, carrying what poses it each frame."""
    corners = part.positions.reshape(-1, 3, 3)
    faces = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    faces /= np.maximum(np.sqrt((faces * faces).sum(axis=1, keepdims=True)), 1e-12)
    skinned = Skinned(rig, part.positions, np.repeat(faces, 3, axis=0), part.joints, part.weights, scale, origin)
    positions, normals = skinned.posed({})
    colour = _rgb(part.colour)
    texture = _image(part.texture)
    surface = own or Surface(diffuse=colour, ambient=colour, opacity=part.colour[3], albedo_map=texture)
    uvs = part.uvs.astype(np.float32)
    return Piece(link, positions.astype(np.float32), normals.astype(np.float32), uvs, surface, skin=skinned)


def _primitive(geometry: Geometry) -> Tessellated | None:
    """A box, sphere, cylinder or capsule tessellated (`shapes.primitive`, PyBullet's sizes: length
    before radius); None for a shape the URDF draws as a mesh or not at all."""
    if isinstance(geometry, Box):
        return primitive(GEOM_BOX, geometry.size)
    if isinstance(geometry, Sphere):
        return primitive(GEOM_SPHERE, (geometry.radius,))
    if isinstance(geometry, Cylinder):
        return primitive(GEOM_CYLINDER, (geometry.length, geometry.radius))
    if isinstance(geometry, Capsule):
        return primitive(GEOM_CAPSULE, (geometry.length, geometry.radius))
    return None


def _mesh_parts(mesh: Mesh) -> list[tuple[Tessellated, Surface | None]]:
    """The mesh file's submeshes, scaled as the visual says, each with its own material."""
    if mesh.path is None:
        return []
    parts = submeshes(_resolved(mesh.path))
    return [((*scaled(p.positions, p.normals, mesh.scale), p.uvs), p.surface) for p in parts]


def _surface(visual: Visual) -> Surface | None:
    """The visual's own material; None where the visual says nothing of it (no material field
    written, no transparency, casting shadows): a mesh then keeps its own. Where only one of ambient
    and diffuse is written it stands for the other; without either, white."""
    material = visual.material or Material()
    if material == Material() and not visual.transparency and visual.cast_shadows:
        return None
    diffuse = material.diffuse or material.ambient or WHITE
    ambient = material.ambient or material.diffuse or WHITE
    specular, shininess = _specular(material, _rgb(diffuse))
    return Surface(
        diffuse=_rgb(diffuse),
        ambient=_rgb(ambient),
        specular=specular,
        shininess=shininess,
        emissive=_rgb(material.emissive or BLACK),
        opacity=(1.0 - visual.transparency) * diffuse[3],
        lit=material.lighting,
        albedo_map=_image(material.albedo_map),
        normal_map=_image(material.normal_map),
        cast_shadows=visual.cast_shadows,
    )


def _specular(material: Material, diffuse: RGB) -> tuple[RGB, float]:
    """SDF's `<specular>` and `<shininess>` where written; else what PBR's metalness and roughness
    stand for; else none."""
    shininess = material.shininess if (material.shininess or 0.0) > 0.0 else None
    if material.roughness is None:
        return _rgb(material.specular or BLACK), shininess or Surface.shininess
    pbr, exponent = pbr_specular(diffuse, material.metalness or 0.0, material.roughness)
    return pbr if material.specular is None else _rgb(material.specular), shininess or exponent


def _image(path: Path | None) -> str | None:
    """The texture's absolute path where it decodes (a warning names it where not)."""
    if path is None:
        return None
    found = _resolved(path)
    return found if readable_image(found) else None


@functools.lru_cache(maxsize=4096)
def _resolved(path: Path) -> str:
    """Resolved once: every surface that names the texture asks."""
    return str(path.resolve())


def _rgb(values: tuple[float, ...]) -> RGB:
    return (values[0], values[1], values[2])
