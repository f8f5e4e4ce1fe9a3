"""What each collision shape leaves in a height band, in world xy: the pieces simbot.mapping.raster fills.

The band is closed, [low, high]; a band of some thickness is taken 1 µm inside at both ends
(BAND_INSET), so that a shape that only touches it (the floor's top face under a band from z = 0)
is not in it. Per shape, exactly:

- box, plane (its `<size>` rectangle) and every convex solid (a tilted cylinder as a prism of
  PRISM_SIDES sides, ellipsoid and cone as simbot's generated meshes of them): the points where the
  solid meets the band (its vertices inside, its edges through the band's planes); their convex
  hull is the solid's shadow in the band, exact for a polyhedron;
- upright cylinder, sphere, capsule: discs (a sphere's of the widest circle inside the band);
- mesh (OBJ, STL, COLLADA, ... as trimesh reads it; scaled) and polyline: each triangle's part
  inside the band, plus, for a closed mesh, the inside of its cross-section at the band's low end
  (every point of the solid in the band lies under a piece of surface in the band, or above that
  cross-section's inside); an open mesh is its surface alone;
- heightmap (simbot's triangles of it, generated_meshes.heightmap): the terrain where it rises
  above the band's low end, up to any height, as the ground below it is solid.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.description import generated_meshes
from simbot.description.errors import DescriptionError
from simbot.description.footprints import BOX_SIGNS, box_corners, convex_hull
from simbot.description.model import (
    Box,
    Capsule,
    Cone,
    Cylinder,
    Ellipsoid,
    Geometry,
    Heightmap,
    Mesh,
    Plane,
    Polyline,
    Sphere,
)
from simbot.transform import matmul, rpy_to_matrix

log = logging.getLogger(__name__)

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]

BAND_INSET = 1e-6
"""Metres the ends of a band of some thickness are taken inside it (see the module docstring)."""
PRISM_SIDES = 64
"""Sides of the prism a tilted cylinder is cut as: its flats lie 0.12 % of the radius inside the circle."""
UPRIGHT = 1e-9
"""How far from vertical (1 − |cos|) an axis may be and still count as upright."""
BOX_EDGES = np.array(
    [(i, j) for i in range(8) for j in range(i + 1, 8) if np.abs(BOX_SIGNS[i] - BOX_SIGNS[j]).sum() == 2]
)
"""The twelve edges of a box whose corners are `BOX_SIGNS`' (simbot.description.footprints.box_corners)."""
SQUARE_CORNERS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
SQUARE_EDGES = np.array([(0, 1), (1, 2), (2, 3), (3, 0)])


@dataclass(frozen=True)
class Band:
    """Heights, metres in the world: a single height is a band of no thickness."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high)) or self.low > self.high:
            raise ValueError(f"a band's low end must be a number at most its high end, got {self.low}:{self.high}")

    @staticmethod
    def at(height: float) -> Band:
        return Band(height, height)

    def cut(self) -> tuple[float, float]:
        """The heights shapes are cut at: the band, BAND_INSET inside where it has a thickness."""
        if self.high - self.low > 2 * BAND_INSET:
            return self.low + BAND_INSET, self.high - BAND_INSET
        return self.low, self.high


@dataclass
class Pieces:
    """A model's shapes in a band, in world xy, as raster.py fills them."""

    hulls: list[Floats] = field(default_factory=list)
    """Convex polygons (k × 2), in order around each."""
    bits: list[Floats] = field(default_factory=list)
    """Triangles' parts in the band: n × 9 × 2 points of convex pieces, NaN where unused."""
    discs: list[tuple[float, float, float]] = field(default_factory=list)
    sections: list[Floats] = field(default_factory=list)
    """Closed loops (m × 2 × 2 segments), one array per closed mesh: their inside is occupied."""
    bounds: list[Floats] = field(default_factory=list)
    """Points (k × 2) spanning each whole shape (all heights): what a map's extent holds."""
    floor_bounds: list[Floats] = field(default_factory=list)
    """The same for planes, which span a map only where nothing else does."""


def add_collision(pieces: Pieces, geometry: Geometry, frame: Floats, band: Band, source: Path | None) -> None:
    """Adds what `geometry`, placed in the world by `frame` (4 × 4), leaves in `band` to `pieces`."""
    low, high = band.cut()
    match geometry:
        case Box(size=size):
            _convex(pieces, box_corners(size, frame), BOX_EDGES, low, high)
        case Cylinder(radius=radius, length=length):
            _cylinder(pieces, radius, length, frame, low, high)
        case Sphere(radius=radius):
            _sphere(pieces, radius, frame[:3, 3], low, high)
        case Capsule(radius=radius, length=length):
            _cylinder(pieces, radius, length, frame, low, high)
            for end in (-length / 2, length / 2):
                _sphere(pieces, radius, frame[:3, 3] + frame[:3, 2] * end, low, high)
        case Ellipsoid() | Cone():
            vertices, faces = (
                generated_meshes.ellipsoid(geometry)
                if isinstance(geometry, Ellipsoid)
                else generated_meshes.cone(geometry)
            )
            _convex(pieces, _placed(vertices, frame), _edges(faces)[0], low, high)
        case Plane(normal=normal, size=(sx, sy)):
            _plane(pieces, normal, (sx, sy), frame, low, high)
        case Polyline():
            vertices, faces = generated_meshes.polyline(geometry)
            _surface(pieces, _placed(vertices, frame), faces, True, low, high)
        case Mesh(path=path, scale=scale):
            _mesh(pieces, geometry, path, scale, frame, low, high)
        case Heightmap():
            _heightmap(pieces, geometry, frame, source, low)


def _placed(points: Floats, frame: Floats) -> Floats:
    """Points (n × 3) of a shape's frame in the world."""
    placed: Floats = matmul(points, frame[:3, :3].T) + frame[:3, 3]
    return placed


def _edges(faces: Ints) -> tuple[Ints, Ints]:
    """The unique edges (lower vertex index first) of triangles, and how many triangles hold each."""
    pairs = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges, counts = np.unique(pairs, axis=0, return_counts=True)
    return edges, counts


def _slab_points(vertices: Floats, edges: Ints, low: float, high: float) -> Floats:
    """Where a convex solid meets the band: its vertices inside and its edges through the band's ends (k × 2)."""
    z = vertices[:, 2]
    found = [vertices[(z >= low) & (z <= high), :2]]
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    for plane in {low, high}:
        da, db = a[:, 2] - plane, b[:, 2] - plane
        through = da * db < 0
        t = (da[through] / (da[through] - db[through]))[:, None]
        found.append(a[through, :2] + t * (b[through, :2] - a[through, :2]))
    return np.concatenate(found)


def _convex(pieces: Pieces, vertices: Floats, edges: Ints, low: float, high: float) -> None:
    pieces.bounds.append(vertices[:, :2])
    points = _slab_points(vertices, edges, low, high)
    if len(points):
        pieces.hulls.append(convex_hull(points))


def _cylinder(pieces: Pieces, radius: float, length: float, frame: Floats, low: float, high: float) -> None:
    """Upright: its disc where its height meets the band. Tilted: the prism of PRISM_SIDES sides in it."""
    axis, centre = frame[:3, 2], frame[:3, 3]
    if abs(axis[2]) >= 1.0 - UPRIGHT:
        pieces.bounds.append(centre[:2] + radius * np.array([[-1.0, -1.0], [1.0, 1.0]]))
        if centre[2] - length / 2 <= high and centre[2] + length / 2 >= low:
            pieces.discs.append((float(centre[0]), float(centre[1]), radius))
        return
    around = np.linspace(0.0, 2.0 * np.pi, PRISM_SIDES, endpoint=False)
    ring = np.stack([radius * np.cos(around), radius * np.sin(around)], axis=1)
    vertices = np.vstack(
        [np.c_[ring, np.full(PRISM_SIDES, -length / 2)], np.c_[ring, np.full(PRISM_SIDES, length / 2)]]
    )
    k = np.arange(PRISM_SIDES)
    edges = np.concatenate(
        [np.c_[k, (k + 1) % PRISM_SIDES], np.c_[k, (k + 1) % PRISM_SIDES] + PRISM_SIDES, np.c_[k, k + PRISM_SIDES]]
    )
    _convex(pieces, _placed(vertices, frame), edges, low, high)


def _sphere(pieces: Pieces, radius: float, centre: Floats, low: float, high: float) -> None:
    """The widest circle of the sphere inside the band: its equator, or where the band's nearer end cuts it."""
    pieces.bounds.append(centre[:2] + radius * np.array([[-1.0, -1.0], [1.0, 1.0]]))
    off = 0.0 if low <= centre[2] <= high else min(abs(centre[2] - low), abs(centre[2] - high))
    if off < radius:
        pieces.discs.append((float(centre[0]), float(centre[1]), math.sqrt(radius * radius - off * off)))


def _plane(
    pieces: Pieces,
    normal: tuple[float, float, float],
    size: tuple[float, float],
    frame: Floats,
    low: float,
    high: float,
) -> None:
    """The plane's `<size>` rectangle, turned to face its normal: the floor, unless it crosses the band."""
    nx, ny, nz = normal
    norm = math.sqrt(nx * nx + ny * ny + nz * nz) or 1.0
    turn = np.eye(4)
    turn[:3, :3] = rpy_to_matrix((0.0, math.acos(max(-1.0, min(1.0, nz / norm))), math.atan2(ny, nx)))
    vertices = _placed(SQUARE_CORNERS * np.array([size[0] / 2, size[1] / 2, 0.0]), matmul(frame, turn))
    floor = Pieces()
    _convex(floor, vertices, SQUARE_EDGES, low, high)
    pieces.hulls += floor.hulls
    pieces.floor_bounds += floor.bounds


def _surface(pieces: Pieces, vertices: Floats, faces: Ints, closed: bool, low: float, high: float) -> None:
    """A triangle mesh in the world: its triangles' parts in the band, and a closed one's inside."""
    pieces.bounds.append(vertices[:, :2])
    bits = _triangle_bits(vertices[faces], low, high)
    if len(bits):
        pieces.bits.append(bits)
        if closed:
            pieces.sections.append(_section(vertices, faces, low))


def _triangle_bits(triangles: Floats, low: float, high: float) -> Floats:
    """Each triangle's part in the band as the points that span it: its corners inside, its edges
    through the band's finite ends (n × 9 × 2, NaN where unused); triangles missing the band left out."""
    z = triangles[..., 2]
    triangles = triangles[(z.max(axis=1) >= low) & (z.min(axis=1) <= high)]
    z = triangles[..., 2]
    found = [np.where(((z >= low) & (z <= high))[..., None], triangles[..., :2], np.nan)]
    a, b = triangles, np.roll(triangles, -1, axis=1)
    for plane in (low, high):
        if not math.isfinite(plane):
            continue
        da, db = a[..., 2] - plane, b[..., 2] - plane
        through = da * db < 0
        t = np.where(through, da / np.where(through, da - db, 1.0), np.nan)[..., None]
        found.append(a[..., :2] + t * (b[..., :2] - a[..., :2]))
    return np.concatenate(found, axis=1)


def _section(vertices: Floats, faces: Ints, height: float) -> Floats:
    """The loops where a closed mesh crosses `height` (m × 2 × 2): each triangle crossing it gives
    one segment, its ends computed from each edge's lower-indexed vertex so that the two triangles
    sharing an edge agree bit for bit, and the loops close."""
    above = vertices[:, 2] >= height
    ends = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 3, 2)
    a, b = ends.min(axis=2), ends.max(axis=2)
    through = above[a] != above[b]
    pa, pb = vertices[a[through]], vertices[b[through]]
    t = ((height - pa[:, 2]) / (pb[:, 2] - pa[:, 2]))[:, None]
    section: Floats = (pa[:, :2] + t * (pb[:, :2] - pa[:, :2])).reshape(-1, 2, 2)
    return section


def _mesh(
    pieces: Pieces,
    mesh: Mesh,
    path: Path | None,
    scale: tuple[float, float, float],
    frame: Floats,
    low: float,
    high: float,
) -> None:
    if path is None:
        log.warning("map: mesh %r was not found; left out of the map", mesh.uri)
        return
    try:
        vertices, faces, closed = _mesh_file(path)
    except DescriptionError as exc:
        log.warning("map: %s; left out of the map", exc)
        return
    _surface(pieces, _placed(vertices * np.asarray(scale), frame), faces, closed, low, high)


@functools.lru_cache(maxsize=64)
def _mesh_file(path: Path) -> tuple[Floats, Ints, bool]:
    """A mesh file's vertices, triangles and whether it is closed (each edge in two triangles)."""
    import trimesh

    try:
        mesh: Any = trimesh.load(path, force="mesh")
        vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
        raise DescriptionError(path, f"mesh cannot be read ({exc})", "mesh") from None
    counts = _edges(faces)[1]
    return vertices, faces, bool(len(faces)) and bool(np.all(counts == 2))


def _heightmap(pieces: Pieces, heightmap: Heightmap, frame: Floats, source: Path | None, low: float) -> None:
    try:
        vertices, faces = generated_meshes.heightmap(heightmap, source)
    except DescriptionError as exc:
        log.warning("map: %s; left out of the map", exc)
        return
    placed = _placed(vertices, frame)
    pieces.bounds.append(placed[:, :2])
    bits = _triangle_bits(placed[faces], low, math.inf)
    if len(bits):
        pieces.bits.append(bits)
