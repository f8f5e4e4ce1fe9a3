"""Triangle meshes for the SDF shapes that URDF cannot state: ellipsoid, cone, polyline, heightmap.

They are written as OBJ files, named by their content (the same shape is one file however often
it is asked for), so the URDF names them as it names any mesh and every consumer of the URDF —
PyBullet's collision, TinyRenderer, the OpenGL camera renderer — draws them unchanged. PyBullet
collides a dynamic body's mesh by its convex hull: exact for the ellipsoid and the cone (up to
their facets), an approximation for a concave polyline outline (static models collide with the
outline itself, see urdf_writer). A heightmap's collision is a PyBullet heightfield, made by the
simulator from `heightmap_heights`; its mesh here is what cameras see.
"""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path

import numpy as np
import numpy.typing as npt

from simbot.description.errors import DescriptionError
from simbot.description.model import Cone, Ellipsoid, Heightmap, Polyline
from simbot.transform import matmul

logger = logging.getLogger(__name__)

SEGMENTS = 32
"""Facets around an ellipsoid or cone: the flat between two vertices is 0.5 % of the radius deep."""

Vertices = npt.NDArray[np.float64]
Faces = npt.NDArray[np.int64]
Generated = Ellipsoid | Cone | Polyline | Heightmap


def ellipsoid(shape: Ellipsoid) -> tuple[Vertices, Faces]:
    """A UV sphere scaled to the radii, with vertices at both poles (so it rests exactly on one)."""
    rings = SEGMENTS // 2
    polar = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    around = np.linspace(0.0, 2.0 * np.pi, SEGMENTS, endpoint=False)
    ring = np.stack(
        [
            np.outer(np.sin(polar), np.cos(around)),
            np.outer(np.sin(polar), np.sin(around)),
            np.outer(np.cos(polar), np.ones(SEGMENTS)),
        ],
        axis=-1,
    )
    unit = np.vstack([[0.0, 0.0, 1.0], ring.reshape(-1, 3), [0.0, 0.0, -1.0]])
    faces = _cap(0, 1, reverse=False)
    for r in range(rings - 2):
        faces += _band(1 + r * SEGMENTS, 1 + (r + 1) * SEGMENTS)
    faces += _cap(len(unit) - 1, 1 + (rings - 2) * SEGMENTS, reverse=True)
    return unit * np.asarray(shape.radii), np.asarray(faces)


def cone(shape: Cone) -> tuple[Vertices, Faces]:
    """Base circle at z = -length/2, apex at +length/2, as SDF places a cone."""
    around = np.linspace(0.0, 2.0 * np.pi, SEGMENTS, endpoint=False)
    half = shape.length / 2.0
    rim = np.stack([shape.radius * np.cos(around), shape.radius * np.sin(around), np.full(SEGMENTS, -half)], axis=1)
    vertices = np.vstack([[0.0, 0.0, half], rim, [0.0, 0.0, -half]])
    return vertices, np.asarray(_cap(0, 1, reverse=False) + _cap(SEGMENTS + 1, 1, reverse=True))


def _cap(pole: int, first: int, reverse: bool) -> list[tuple[int, int, int]]:
    """Triangles from a pole to a ring of SEGMENTS vertices starting at `first`, facing outwards."""
    tris = [(pole, first + k, first + (k + 1) % SEGMENTS) for k in range(SEGMENTS)]
    return [(a, c, b) for a, b, c in tris] if reverse else tris


def _band(upper: int, lower: int) -> list[tuple[int, int, int]]:
    """Two triangles per facet between two rings of SEGMENTS vertices."""
    faces = []
    for k in range(SEGMENTS):
        k1 = (k + 1) % SEGMENTS
        faces += [(upper + k, lower + k, lower + k1), (upper + k, lower + k1, upper + k1)]
    return faces


def polyline(shape: Polyline) -> tuple[Vertices, Faces]:
    """Each outline extruded from z = 0 to its height: walls and ear-clipped top and bottom."""
    vertices: list[Vertices] = []
    faces: list[Faces] = []
    offset = 0
    for outline, height in zip(shape.outlines, shape.heights):
        points = np.asarray(outline, dtype=float)
        if np.allclose(points[0], points[-1]):
            points = points[:-1]  # a closed outline may repeat its first point
        if _signed_area(points) < 0:
            points = points[::-1]
        n = len(points)
        bottom, top = np.c_[points, np.zeros(n)], np.c_[points, np.full(n, height)]
        caps = _ear_clip(points)
        walls = [(k, (k + 1) % n, n + (k + 1) % n) for k in range(n)] + [(k, n + (k + 1) % n, n + k) for k in range(n)]
        tris = [(c, b, a) for a, b, c in caps] + [(n + a, n + b, n + c) for a, b, c in caps] + walls
        vertices.append(np.vstack([bottom, top]))
        faces.append(np.asarray(tris) + offset)
        offset += 2 * n
    return np.vstack(vertices), np.vstack(faces)


def _signed_area(points: Vertices) -> float:
    x, y = points[:, 0], points[:, 1]
    return float(matmul(x, np.roll(y, -1)) - matmul(np.roll(x, -1), y)) / 2.0


def _ear_clip(points: Vertices) -> list[tuple[int, int, int]]:
    """Triangles of a simple counter-clockwise polygon, by cutting off one convex ear at a time."""
    left = list(range(len(points)))
    tris = []
    while len(left) > 3:
        for i in range(len(left)):
            a, b, c = left[i - 1], left[i], left[(i + 1) % len(left)]
            if _is_ear(points, a, b, c, left):
                tris.append((a, b, c))
                left.pop(i)
                break
        else:
            break  # not a simple polygon: close it as a fan rather than loop
    return tris + [(left[0], left[k], left[k + 1]) for k in range(1, len(left) - 1)]


def _is_ear(points: Vertices, a: int, b: int, c: int, left: list[int]) -> bool:
    pa, pb, pc = points[a], points[b], points[c]
    if _cross(pa, pb, pc) <= 0:
        return False
    return not any(
        _cross(pa, pb, points[p]) >= 0 and _cross(pb, pc, points[p]) >= 0 and _cross(pc, pa, points[p]) >= 0
        for p in left
        if p not in (a, b, c)
    )


def _cross(o: Vertices, a: Vertices, b: Vertices) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def heightmap_heights(shape: Heightmap, file: Path | None = None) -> npt.NDArray[np.float64]:
    """Heights in metres above the heightmap's `pos`, row 0 the image's top (+y), column 0 its left (−x):
    a pixel's grey level over the image type's full scale (255 for 8 bits), times size z."""
    import cv2  # opencv reads PNG, JPEG and TIFF at 8 or 16 bits

    if shape.path is None:
        raise DescriptionError(file, f"heightmap image {shape.uri!r} was not found", "heightmap")
    image = cv2.imread(str(shape.path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_GRAYSCALE)
    if image is None or image.ndim != 2 or min(image.shape) < 2:
        raise DescriptionError(
            file, f"heightmap {shape.path} is not a readable image of at least 2×2 pixels", "heightmap"
        )
    full_scale = (
        float(np.iinfo(image.dtype.name).max) if np.issubdtype(image.dtype, np.integer) else float(image.max() or 1.0)
    )
    return image.astype(np.float64) / full_scale * shape.size[2]


def heightmap(shape: Heightmap, file: Path | None = None) -> tuple[Vertices, Faces]:
    """The height grid as triangles, centred on `pos` in x and y, height 0 at `pos` z."""
    heights = heightmap_heights(shape, file)
    rows, cols = heights.shape
    x = np.linspace(-shape.size[0] / 2.0, shape.size[0] / 2.0, cols) + shape.pos[0]
    y = np.linspace(shape.size[1] / 2.0, -shape.size[1] / 2.0, rows) + shape.pos[1]
    gx, gy = np.meshgrid(x, y)
    vertices = np.stack([gx, gy, heights + shape.pos[2]], axis=-1).reshape(-1, 3)
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = index[:-1, :-1], index[:-1, 1:], index[1:, :-1], index[1:, 1:]  # a b over c d, +y up
    faces = np.concatenate([np.stack([a, c, d], -1).reshape(-1, 3), np.stack([a, d, b], -1).reshape(-1, 3)])
    return vertices, faces


def mesh_file(shape: Generated, folder: Path, file: Path | None = None) -> Path:
    """The OBJ file of `shape` in `folder`, written unless a file of the same content is there."""
    if isinstance(shape, Ellipsoid):
        vertices, faces = ellipsoid(shape)
    elif isinstance(shape, Cone):
        vertices, faces = cone(shape)
    elif isinstance(shape, Polyline):
        vertices, faces = polyline(shape)
    else:
        vertices, faces = heightmap(shape, file)
    text = "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in vertices) + "".join(
        f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces
    )
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = folder / f"simbot_{type(shape).__name__.lower()}_{digest}.obj"
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        logger.debug("wrote the %s mesh %s (%d triangles)", type(shape).__name__.lower(), path, len(faces))
    return path
