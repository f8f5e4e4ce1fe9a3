"""The OpenGL renderer's parts (`gl.py`): each a vertex buffer drawn with one transform and one
surface, and the interleaved vertex rows they hold."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render import gl_shaders as shaders
from simbot.sim.render.skinning import Skinned
from simbot.sim.render.surfaces import Piece, Surface
from simbot.transform import Matrix, matmul

Rows = npt.NDArray[np.float32]
ROW = "3f 3f 2f 1u 1f"
"""A vertex: position, normal, texture coordinates (float32), its visual's packed label (uint32,
`label_bits.py`) and temperature (float32, K; below zero: none): 40 bytes."""


@dataclass
class Part:
    """A vertex buffer drawn with one transform and one surface: a batch of the static world, or
    one surface of a moving link."""

    buffer: Any
    vao: Any
    depth_vao: Any
    """For the depth-only program: the sun's shadow maps."""
    annotation_vao: Any
    """For the annotation program: labels and temperatures."""
    body: str | None
    """None for the static world (identity transform)."""
    link: int
    surface: Surface
    texture: Any | None
    normal_map: Any | None
    program: shaders.Program
    material: shaders.Material
    """Its surface's uniforms, packed once."""
    centre: npt.NDArray[np.float64]
    """Its bounding sphere's centre, in its own frame (the world's, or its link's), and radius (`culling.py`)."""
    radius: float
    skin: Skinned | None = None
    """A skinned part: its vertices are posed anew for each pose (`skinning.py`) ..."""
    rows: Rows | None = None
    """... into these rows, then its buffer."""

    def release(self) -> None:
        for item in (self.vao, self.depth_vao, self.annotation_vao, self.buffer):
            item.release()


def stacked(arrays: list[Rows]) -> Rows:
    """Vertex rows one after the other; no rows for no arrays."""
    return np.concatenate(arrays) if arrays else np.empty((0, 10), dtype=np.float32)


def vertex_rows(piece: Piece, link_to_world: Matrix) -> Rows:
    """Interleaved rows of the piece (`ROW`), transformed by `link_to_world`; the label's uint32
    bits ride in a float32 column (copied, never computed on)."""
    rotation = link_to_world[:3, :3]
    positions = matmul(piece.positions, rotation.T) + link_to_world[:3, 3]
    normals = matmul(piece.normals, rotation.T)
    count = len(piece.positions)
    label = np.full((count, 1), piece.label, dtype=np.uint32).view(np.float32)
    temperature = np.full((count, 1), -1.0 if np.isnan(piece.temperature) else piece.temperature, dtype=np.float32)
    return np.hstack(
        [positions.astype(np.float32), normals.astype(np.float32), piece.uvs.astype(np.float32), label, temperature]
    )
