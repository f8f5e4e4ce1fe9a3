"""What a renderer shades: each visual of a body as pieces of triangles, one material each.

A visual becomes one piece per material it holds: a box or a sphere is one piece, a mesh file
with three materials three (the materials a mesh file gives its submeshes are kept; an SDF
`<material>` on the visual replaces them all, as in Gazebo). Positions, normals and texture
coordinates are per vertex, three rows a triangle, in the visual's link frame.

`Surface` is Gazebo's material model as SDF writes it (ambient, diffuse, specular, emissive,
`<lighting>`, the visual's `<transparency>`; PBR's albedo and normal maps), the one shape of it
every source is turned into: SDF materials, URDF colours, OBJ/MTL, COLLADA and glTF materials.
Textures are named by file; a worker reads each image once when the scene loads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

RGB = tuple[float, float, float]
Floats = npt.NDArray[np.float32]


@dataclass(frozen=True)
class Surface:
    """How a piece is shaded. Colours are linear 0..1; an albedo map multiplies `diffuse` and
    `ambient` (Gazebo: the texture replaces the colour's hue, the colour tints it)."""

    diffuse: RGB = (0.7, 0.7, 0.7)
    ambient: RGB = (0.7, 0.7, 0.7)
    specular: RGB = (0.0, 0.0, 0.0)
    shininess: float = 32.0
    """Blinn-Phong exponent of the specular highlight."""
    emissive: RGB = (0.0, 0.0, 0.0)
    opacity: float = 1.0
    """1 − SDF `<transparency>`, times the diffuse colour's alpha."""
    lit: bool = True
    """SDF `<lighting>`: False draws the diffuse colour (or texture) as is, unshaded."""
    albedo_map: str | None = None
    """Absolute path of the colour texture (PBR `albedo_map`, MTL `map_Kd`, COLLADA/glTF base colour)."""
    normal_map: str | None = None
    """Absolute path of a tangent-space normal map (PBR `normal_map`)."""
    cast_shadows: bool = True
    """SDF `<visual><cast_shadows>`."""


@dataclass(frozen=True, eq=False)
class Piece:
    """Triangles of one visual with one surface, in the frame of link `link` (-1: the base)."""

    link: int
    positions: Floats
    """N×3, three rows a triangle."""
    normals: Floats
    """N×3, unit length."""
    uvs: Floats
    """N×2 texture coordinates (OpenGL's: v up from the image's bottom row); zeros where the
    source has none."""
    surface: Surface
    label: int = 0
    """The label and instance of its visual, packed (`label_bits.py`)."""
    temperature: float = float("nan")
    """Its temperature (K) from the Thermal system; NaN: the atmosphere's where it is."""
    skin: Any = None
    """A skinned part's `skinning.Skinned` (posed each frame; `positions` are its bind pose), else None."""
