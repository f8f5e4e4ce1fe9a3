"""Mesh files PyBullet cannot load (glTF, GLB, PLY, ...): an OBJ of the same triangles for it.

PyBullet's URDF loader reads OBJ, STL and COLLADA only. For any other format trimesh reads, the
URDF names an OBJ of the file's triangles (no materials), written once to the generated-mesh
folder under the source file's content hash (and the file itself beside it, in urdf_writer's
`<sdf_material mesh=...>`); the renderers draw the original file, which the description's visual
names (urdf_visuals.py), with its materials and textures.

A skinned COLLADA file (an actor's skin whose scene holds `<instance_controller>`s and no
`<instance_geometry>`) is one too: PyBullet's COLLADA loader (and trimesh's) reads instanced
geometry only, so it would load empty and TinyRenderer would draw no one. Its stand-in is the
skin in its bind pose (simbot.description.skeletons), what the GL renderer draws unposed.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from simbot.description.errors import DescriptionError
from simbot.description.skeletons import SkeletonError, read_skeleton

PYBULLET_SUFFIXES = (".obj", ".stl", ".dae")
"""What PyBullet's URDF loader reads itself."""

logger = logging.getLogger(__name__)


def needs_stand_in(path: Path) -> bool:
    return path.suffix.lower() not in PYBULLET_SUFFIXES or skinned_only(path)


@cache
def skinned_only(path: Path) -> bool:
    """Whether a COLLADA file's scene instances controllers (skins) and no geometry: what PyBullet
    loads as nothing."""
    if path.suffix.lower() != ".dae":
        return False
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return False
    return re.search(r"<instance_controller\b", text) is not None and re.search(r"<instance_geometry\b", text) is None


def stand_in(path: Path, folder: Path) -> Path:
    """An OBJ of `path`'s triangles in `folder` (written once); a DescriptionError naming the file
    when trimesh cannot read it."""
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    target = folder / f"{path.stem}_{digest}.obj"
    if target.is_file():
        return target
    try:
        text = _bind_pose_obj(path) if skinned_only(path) else _trimesh_obj(path)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
        raise DescriptionError(path, f"mesh cannot be read ({exc})", "mesh") from None
    folder.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(f".{os.getpid()}.part")
    partial.write_text(text)
    os.replace(partial, target)  # whole or absent, for another process writing it at the same time
    logger.debug("wrote %s for PyBullet, which cannot read %s", target, path)
    return target


def _trimesh_obj(path: Path) -> str:
    import trimesh

    mesh: Any = trimesh.load(path, force="mesh")
    return str(mesh.export(file_type="obj", include_texture=False, include_normals=False))


def _bind_pose_obj(path: Path) -> str:
    """The skin's triangles in its bind pose as OBJ text (each triangle its own three vertices)."""
    try:
        parts = read_skeleton(path).parts
    except SkeletonError as exc:
        raise ValueError(str(exc)) from None
    positions = np.concatenate([part.positions for part in parts])
    vertices = "".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in positions.tolist())
    faces = "".join(f"f {k + 1} {k + 2} {k + 3}\n" for k in range(0, len(positions), 3))
    return vertices + faces
