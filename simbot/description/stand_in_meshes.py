"""Mesh files PyBullet cannot load (glTF, GLB, PLY, ...): an OBJ of the same triangles for it.

PyBullet's URDF loader reads OBJ, STL and COLLADA only. For any other format trimesh reads, the
URDF names an OBJ of the file's triangles (no materials), written once to the generated-mesh
folder under the source file's content hash (and the file itself beside it, in urdf_writer's
`<sdf_material mesh=...>`); the renderers draw the original file, which the description's visual
names (urdf_visuals.py), with its materials and textures.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path
from typing import Any

from simbot.description.errors import DescriptionError

PYBULLET_SUFFIXES = (".obj", ".stl", ".dae")
"""What PyBullet's URDF loader reads itself."""

logger = logging.getLogger(__name__)


def needs_stand_in(path: Path) -> bool:
    return path.suffix.lower() not in PYBULLET_SUFFIXES


def stand_in(path: Path, folder: Path) -> Path:
    """An OBJ of `path`'s triangles in `folder` (written once); a DescriptionError naming the file
    when trimesh cannot read it."""
    import trimesh

    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    target = folder / f"{path.stem}_{digest}.obj"
    if target.is_file():
        return target
    try:
        mesh: Any = trimesh.load(path, force="mesh")
        text = mesh.export(file_type="obj", include_texture=False, include_normals=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
        raise DescriptionError(path, f"mesh cannot be read ({exc})", "mesh") from None
    folder.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(f".{os.getpid()}.part")
    partial.write_text(text)
    os.replace(partial, target)  # whole or absent, for another process writing it at the same time
    logger.debug("wrote %s for PyBullet, which cannot read %s", target, path)
    return target
