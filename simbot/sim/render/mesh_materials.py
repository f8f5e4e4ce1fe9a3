"""A mesh file's submeshes with their own materials: OBJ/MTL, COLLADA, glTF/GLB (trimesh reads them
as a scene, so each geometry keeps its node transform, texture coordinates and material).

Textures: trimesh hands over decoded images, not their files, so each image a mesh's material
holds is written once as a PNG to a cache folder (`texture_cache`), named by the hash of its
pixels: a worker (or a second worker) finding it there reads it, a texture shared by submeshes is
one file, and an edited texture (a mesh file's MTL or image changes, not the mesh file) gets a
new name. Bad input is one warning naming the file, never an exception: a mesh that cannot be
read, or in which trimesh finds no triangle, is not drawn; materials that cannot be read leave the
mesh uncoloured; a texture that is missing or that OpenCV cannot decode leaves its material's colour.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np
import numpy.typing as npt

from simbot.sim.render import textures
from simbot.sim.render.surfaces import RGB, Surface
from simbot.transform import inverse3, matmul

log = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F0_DIELECTRIC = 0.04
"""The specular reflectance of a non-metal at normal incidence (PBR's usual constant)."""


@dataclass(frozen=True)
class Submesh:
    """Triangles of one material of a mesh file, in the file's frame, unscaled; three rows a triangle."""

    positions: F64
    normals: F64
    uvs: F64
    """Zeros where the file has none."""
    surface: Surface | None
    """None where the file gives no material (the visual's colour applies)."""


def pbr_specular(base: RGB, metalness: float, roughness: float) -> tuple[RGB, float]:
    """(specular colour, Blinn-Phong exponent) standing for a metal/roughness material: the
    reflectance goes from a dielectric's to the base colour with metalness; the exponent is the
    one whose lobe matches the roughness (2/r² − 2, the mapping trimesh uses for COLLADA's)."""
    specular = tuple(F0_DIELECTRIC + (c - F0_DIELECTRIC) * metalness for c in base)
    return specular, max(2.0 / max(roughness, 0.05) ** 2 - 2.0, 1.0)  # type: ignore[return-value]


def scaled(positions: F64, normals: F64, scale: tuple[float, ...]) -> tuple[F64, F64]:
    """Positions scaled; normals by the inverse scale, renormalised (a mirroring scale mirrors them too)."""
    factors = np.asarray(scale[:3], dtype=np.float64)
    turned = normals / np.where(factors == 0.0, 1.0, factors)
    length = np.linalg.norm(turned, axis=1, keepdims=True)
    return positions * factors, turned / np.where(length == 0.0, 1.0, length)


@cache
def submeshes(path: str) -> tuple[Submesh, ...]:
    """The file's submeshes (cached per file); none, and a warning, when it cannot be read."""
    import trimesh  # yourdfpy's dependency: STL, OBJ, PLY, glTF; COLLADA through pycollada

    try:
        scene: Any = trimesh.load(path, force="scene")
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
        log.warning("mesh %s cannot be read (%s); it is not drawn", path, exc)
        return ()
    own_materials = _material_files_readable(Path(path))
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry[name]
        if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
            parts.append(_submesh(path, geometry, np.asarray(transform, dtype=np.float64), own_materials))
    if not parts:
        log.warning("mesh %s holds no triangle that can be read; it is not drawn", path)
    return tuple(parts)


def _submesh(path: str, geometry: Any, transform: F64, own_materials: bool) -> Submesh:
    faces = np.asarray(geometry.faces)
    positions = np.asarray(geometry.vertices, dtype=np.float64)[faces].reshape(-1, 3)
    normals = np.repeat(np.asarray(geometry.face_normals, dtype=np.float64), 3, axis=0)
    normals = matmul(normals, inverse3(transform[:3, :3]))  # by the inverse transpose of the turn
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    uv = getattr(geometry.visual, "uv", None)
    has_uv = uv is not None and len(uv) == len(geometry.vertices)
    uvs = np.asarray(uv, dtype=np.float64)[faces].reshape(-1, 2) if has_uv else np.zeros((len(positions), 2))
    try:
        surface = _surface(geometry.visual) if own_materials else None
    except Exception as exc:  # noqa: BLE001 - a material trimesh half-read can fail anywhere
        log.warning("mesh %s: the materials cannot be read (%s); it is drawn in the visual's colour", path, exc)
        surface = None
    return Submesh(matmul(positions, transform[:3, :3].T) + transform[:3, 3], normals, uvs, surface)


def _surface(visual: Any) -> Surface | None:
    """The submesh's material as a Surface: MTL's (trimesh's SimpleMaterial) or glTF's and
    COLLADA's (its PBRMaterial); a plain colour for vertex or face colours; None without any."""
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    material = getattr(visual, "material", None)
    if isinstance(material, SimpleMaterial):
        image = material.image
        return _mtl_surface(material, None if image is None else texture_file(image))
    if isinstance(material, PBRMaterial):
        image = material.baseColorTexture
        return _pbr_surface(material, None if image is None else texture_file(image))
    return Surface(*(_rgb(visual.main_color),) * 2) if getattr(visual, "defined", False) else None


def _pbr_surface(material: Any, albedo: str | None) -> Surface:
    """glTF's metal/roughness material (and COLLADA's, which trimesh turns into one)."""
    base = np.asarray(material.baseColorFactor if material.baseColorFactor is not None else (255,) * 4) / 255.0
    emissive = material.emissiveFactor if material.emissiveFactor is not None else (0.0, 0.0, 0.0)
    specular, shininess = pbr_specular(
        _rgb(base), _or(material.metallicFactor, 0.0), _or(material.roughnessFactor, 1.0)
    )
    return Surface(_rgb(base), _rgb(base), specular, shininess, _rgb(emissive), float(base[3]), albedo_map=albedo)


def _mtl_surface(material: Any, albedo: str | None) -> Surface:
    """OBJ/MTL: Kd, Ka, Ks, Ns, Ke, and d (or 1 − Tr) as written."""
    values = {key.lower(): value for key, value in material.kwargs.items()}
    diffuse = _floats(values.get("kd"), (0.8, 0.8, 0.8))
    opacity = _floats(values.get("d"), None) or tuple(1.0 - t for t in _floats(values.get("tr"), (0.0,)))
    return Surface(
        diffuse=_rgb(diffuse),
        ambient=_rgb(_floats(values.get("ka"), diffuse)),
        specular=_rgb(_floats(values.get("ks"), (0.0, 0.0, 0.0))),
        shininess=_floats(values.get("ns"), (Surface.shininess,))[0],
        emissive=_rgb(_floats(values.get("ke"), (0.0, 0.0, 0.0))),
        opacity=opacity[0],
        albedo_map=albedo,
    )


def _floats(value: Any, default: Any) -> Any:
    """An MTL statement's numbers (trimesh keeps them as text or numbers), or `default`."""
    if value is None:
        return default
    return tuple(float(v) for v in np.atleast_1d(value))


def _or(value: float | None, default: float) -> float:
    return default if value is None else float(value)


def _rgb(values: Any) -> RGB:
    """The first three of 0..1 numbers, or of 0..255 bytes."""
    array = np.asarray(values)
    scaled_values = array / 255.0 if array.dtype == np.uint8 else array.astype(np.float64)
    return tuple(float(c) for c in scaled_values[:3])  # type: ignore[return-value]


def texture_cache() -> Path:
    """Where a mesh's embedded or decoded textures are written as files."""
    return textures.cache_dir() / "mesh-textures"


def texture_file(image: Any) -> str:
    """The image (PIL) as a PNG in the cache, written once."""
    pixels = image.tobytes()
    digest = hashlib.sha256(f"{image.mode} {image.size}".encode() + pixels).hexdigest()[:24]
    target = texture_cache() / f"{digest}.png"
    if not target.is_file():
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(f".{os.getpid()}.part")
        converted = image if image.mode in ("RGB", "RGBA", "L", "LA") else image.convert("RGBA")
        converted.save(partial, format="PNG")
        os.replace(partial, target)  # whole or absent, for a worker reading it at the same time
    return str(target)


@cache
def readable_image(path: str) -> bool:
    """Whether OpenCV decodes the image (what a renderer reads it with); a warning naming it if not."""
    import cv2

    reason = "is missing" if not os.path.isfile(path) else None
    if reason is None and not textures.known(path) and cv2.imread(path, cv2.IMREAD_UNCHANGED) is None:
        reason = "is not an image OpenCV can decode"
    if reason:
        log.warning("texture %s %s; its material's colour is used", path, reason)
    return reason is None


_MAP_KD = re.compile(r"^\s*map_Kd\s+(?:-\S+\s+\S+\s+)*(.+?)\s*$", re.MULTILINE)
_MTLLIB = re.compile(r"^\s*mtllib\s+(.+?)\s*$", re.MULTILINE)
_DAE_IMAGE = re.compile(r"<image\b[^>]*>\s*<init_from>\s*(?:<ref>)?\s*([^<]+?)\s*<", re.IGNORECASE)


def _material_files_readable(mesh: Path) -> bool:
    """Whether the materials the mesh names are there (an OBJ's MTL libraries: without them trimesh
    makes up a grey material). trimesh drops a texture it cannot load without a word: this says
    which, once each."""
    suffix = mesh.suffix.lower()
    if suffix == ".dae":
        text = mesh.read_text(errors="replace")
        images = [mesh.parent / unquote(name.removeprefix("file://")) for name in _DAE_IMAGE.findall(text)]
    elif suffix == ".obj":
        libraries = [mesh.parent / name for name in _MTLLIB.findall(mesh.read_text(errors="replace"))]
        missing = [library for library in libraries if not library.is_file()]
        if missing:
            log.warning("mesh %s: material library %s is missing; it is drawn in the visual's colour", mesh, missing[0])
            return False
        images = [lib.parent / name for lib in libraries for name in _MAP_KD.findall(lib.read_text(errors="replace"))]
    else:
        return True
    for image in images:
        readable_image(str(image))  # the warning, for one that cannot be read
    return True
