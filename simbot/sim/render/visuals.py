"""Each body's visuals as the pieces a renderer shades (`surfaces.py`), read from the scene."""

from __future__ import annotations

import numpy as np

from simbot.sim.render.scene import BulletScene
from simbot.sim.render.shapes import triangles
from simbot.sim.render.surfaces import Piece, Surface


def body_pieces(scene: BulletScene, name: str) -> list[Piece]:
    """The body's visuals in their link frames, one piece each, coloured as PyBullet reports them."""
    pieces = []
    for shape in scene.visual_shapes(name):
        positions, normals = triangles(shape)
        if len(positions):
            rgb = tuple(float(c) for c in shape.rgba[:3])
            surface = Surface(diffuse=rgb, ambient=rgb, opacity=float(shape.rgba[3]))  # type: ignore[arg-type]
            uvs = np.zeros((len(positions), 2), dtype=np.float32)
            pieces.append(Piece(shape.link, positions, normals, uvs, surface))
    return pieces
