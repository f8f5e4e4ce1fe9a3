"""A body's collision geometry as triangles, for the ray engine: the shapes PyBullet collides with,
read from the description the body was loaded from, each in the URDF frame of the link PyBullet
simulates it as part of (`Part`), so that posing a part is one transform.

Curved shapes are tessellated finely enough that no point of a facet lies more than `SAG_M`/2 off
the true surface, its corners outside and its middle inside by as much (`_straddle`): a ray meets
them within a fraction of a millimetre of where it meets the round shape, where PyBullet's own
cylinders are 32-sided hulls up to 8 mm inside. A mesh is its convex hull where PyBullet
collides with the hull (every mesh of a URDF but a static polyline, which it collides with as it is).
A shape the engine cannot make triangles of (a mesh that cannot be read, no triangles, zero size) is
one logged line naming the model, link and file; the rest of the body is cast against.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.description import generated_meshes
from simbot.description.kinematics import KinematicTree
from simbot.description.model import (
    Box,
    Capsule,
    Collision,
    Cone,
    Cylinder,
    Ellipsoid,
    Geometry,
    Heightmap,
    Link,
    Mesh,
    Model,
    Plane,
    Polyline,
    Sphere,
)
from simbot.description.model_memo import per_model
from simbot.description.poses import IDENTITY, Pose
from simbot.description.stand_in_meshes import needs_stand_in, stand_in
from simbot.description.urdf_writer import in_urdf_link, plane_box, shape_origin
from simbot.sim.physics.body import Body
from simbot.transform import matmul

log = logging.getLogger(__name__)

Triangles = npt.NDArray[np.float64]
"""K×3×3: each triangle's three corners."""

SAG_M = 2.5e-4
"""How deep a facet of a tessellated curve may lie inside the true surface."""
MIN_SEGMENTS = 12


@dataclass(frozen=True)
class Part:
    """The triangles of one PyBullet link of a body, in that link's URDF frame."""

    body: str
    index: int
    """PyBullet's link index (-1: the base)."""
    triangles: Triangles
    radius: float
    """The farthest corner from the link frame's origin: the part's bounding sphere."""


def body_parts(body: Body, folder: Path) -> list[Part]:
    """The triangles of every collision of the body's model, grouped by PyBullet link (each in the
    URDF frame of its host, `Body.hosts`); meshes generated for them go to `folder`. Worked out once
    for every body of one model loaded alike (a fleet's tugs), the arrays shared and read-only."""
    links = tuple(sorted(body.links.items()))
    hosts = tuple(sorted(body.hosts.items()))
    return [
        Part(body.name, index, triangles, radius)
        for index, triangles, radius in _parts(body.model, body.tree, links, hosts, folder)
    ]


@per_model
def _parts(
    model: Model,
    tree: KinematicTree,
    links: tuple[tuple[str, int], ...],
    hosts: tuple[tuple[str, str], ...],
    folder: Path,
) -> list[tuple[int, Triangles, float]]:
    """(PyBullet link index, triangles, bounding radius) of each link with collisions (`body_parts`)."""
    index_of, host_of = dict(links), dict(hosts)
    by_index: dict[int, list[Triangles]] = {}
    for link in model.links:
        if link.name not in index_of:
            continue
        host = _fixed_chain(tree, host_of.get(link.name, link.name), link.name) @ in_urdf_link(link)
        for collision in link.collisions:
            local = _collision_triangles(model, link, collision, folder)
            if local is not None and len(local):
                by_index.setdefault(index_of[link.name], []).append(placed(local, host @ _origin(collision)))
    parts = []
    for index, pieces in sorted(by_index.items()):
        triangles = np.concatenate(pieces)
        triangles.flags.writeable = False
        parts.append((index, triangles, float(np.linalg.norm(triangles, axis=2).max())))
    return parts


def _fixed_chain(tree: KinematicTree, host: str, link: str) -> Pose:
    """`link`'s URDF frame in `host`'s, through the fixed joints between them (merged into `host`)."""
    parents = {joint.child: joint for joint in tree.joints}
    pose = IDENTITY
    while link != host and link in parents:
        pose = parents[link].origin @ pose
        link = parents[link].parent
    return pose


def _origin(collision: Collision) -> Pose:
    """The collision's frame in its SDF link's, a plane's that of the thin box PyBullet has."""
    return shape_origin(IDENTITY, collision)


def placed(triangles: Triangles, pose: Pose) -> Triangles:
    """`triangles` (in `pose`'s frame) in the frame `pose` is given in."""
    matrix = pose.matrix()
    return matmul(triangles.reshape(-1, 3), matrix[:3, :3].T).reshape(-1, 3, 3) + matrix[:3, 3]


def _collision_triangles(model: Model, link: Link, collision: Collision, folder: Path) -> Triangles | None:
    """One collision's triangles in its own frame; None, and one logged line, where there are none."""
    geometry = collision.geometry
    try:
        triangles = shape_triangles(geometry, model, folder)
    except Exception as exc:  # noqa: BLE001 - trimesh and the readers raise many kinds for a bad file
        why = f"cannot be read ({exc})"
    else:
        if triangles is not None and len(triangles) and float(np.ptp(triangles.reshape(-1, 3), axis=0).max()) > 0.0:
            return triangles
        why = "has zero size" if triangles is not None and len(triangles) else "has no triangles"
    _left_out(model, link, geometry, why)
    return None


def _left_out(model: Model, link: Link, geometry: Geometry, why: str) -> None:
    """The one line a shape the engine leaves out is: its model, link and file, and why."""
    where = getattr(geometry, "path", None) or getattr(geometry, "uri", type(geometry).__name__.lower())
    log.warning("ray engine: model %r, link %r: %s %s; lidars see the rest", model.name, link.name, where, why)


def shape_triangles(geometry: Geometry, model: Model, folder: Path) -> Triangles | None:
    """The shape's triangles in its frame (None for a mesh not found, already warned of by the loader)."""
    if isinstance(geometry, Box):
        return box(np.asarray(geometry.size, dtype=float))
    if isinstance(geometry, Plane):
        return box(np.asarray(plane_box(geometry).size, dtype=float))
    if isinstance(geometry, Sphere):
        return capsule(geometry.radius, 0.0)
    if isinstance(geometry, Capsule):
        return capsule(geometry.radius, geometry.length)
    if isinstance(geometry, Cylinder):
        return cylinder(geometry.radius, geometry.length)
    if isinstance(geometry, Mesh):
        if geometry.path is None:
            return None
        path = stand_in(geometry.path, folder) if needs_stand_in(geometry.path) else geometry.path
        return mesh_file(path, tuple(geometry.scale), hull=True)
    if isinstance(geometry, Ellipsoid | Cone | Polyline):
        return _generated(geometry, hull=not (model.static and isinstance(geometry, Polyline)))
    if isinstance(geometry, Heightmap):
        vertices, faces = generated_meshes.heightmap(geometry, model.source)
        return vertices[faces] if model.static else None  # PyBullet collides with static heightmaps only
    return None


def _generated(shape: Ellipsoid | Cone | Polyline, hull: bool) -> Triangles:
    """The mesh generated_meshes writes for PyBullet, its hull where PyBullet collides with that."""
    maker = {Ellipsoid: generated_meshes.ellipsoid, Cone: generated_meshes.cone, Polyline: generated_meshes.polyline}
    vertices, faces = maker[type(shape)](shape)  # type: ignore[operator]
    return _hull(vertices) if hull else vertices[faces]


def segments(radius: float) -> int:
    """Facets around a circle of `radius` so that an inscribed one would lie at most SAG_M inside it."""
    if radius <= SAG_M:
        return MIN_SEGMENTS
    return max(MIN_SEGMENTS, math.ceil(math.pi / math.acos(1.0 - SAG_M / radius)))


def box(size: npt.NDArray[np.float64]) -> Triangles:
    """The twelve triangles of a box of `size`, centred."""
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]) * size
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1)]
    faces += [(2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return corners[np.asarray(faces)]


def cylinder(radius: float, length: float) -> Triangles:
    """A closed cylinder along z, centred: its sides and two caps."""
    n = segments(radius)
    ring = _ring(radius * _straddle(n), n)
    low, high = np.full((len(ring), 1), -length / 2.0), np.full((len(ring), 1), length / 2.0)
    return _revolved([np.c_[ring * 0.0, low], np.c_[ring, low], np.c_[ring, high], np.c_[ring * 0.0, high]])


def capsule(radius: float, length: float) -> Triangles:
    """A capsule along z, centred (a sphere where `length` is 0): two half spheres and the cylinder between."""
    n = segments(radius)
    polar = np.linspace(0.0, math.pi / 2, max(3, n // 4) + 1)
    r = radius * _straddle(n)
    upper = [np.c_[_ring(r * math.sin(p), n), [length / 2 + r * math.cos(p)] * n] for p in polar]
    lower = [np.c_[ring[:, :2], -ring[:, 2]] for ring in upper]  # the bottom pole up to the bottom rim
    return _revolved(lower + upper[::-1])


def _straddle(n: int) -> float:
    """The corners' radius over the true one that puts an `n`-gon's corners as far outside the
    circle as its flats' middles are inside: a ray's error is then either way, half the facets' depth."""
    return 2.0 / (1.0 + math.cos(math.pi / n))


def _ring(radius: float, n: int) -> npt.NDArray[np.float64]:
    """`n` points on a circle of `radius`."""
    around = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.stack([radius * np.cos(around), radius * np.sin(around)], axis=1)


def _revolved(rings: list[npt.NDArray[np.float64]]) -> Triangles:
    """The bands between consecutive rings of equal size (a degenerate ring is a pole)."""
    n = len(rings[0])
    nxt = (np.arange(n) + 1) % n
    bands = []
    for low, high in zip(rings[:-1], rings[1:]):
        a, b, c, d = low, low[nxt], high, high[nxt]
        bands += [np.stack([a, b, d], axis=1), np.stack([a, d, c], axis=1)]
    return np.concatenate(bands)


@functools.lru_cache(maxsize=256)
def mesh_file(path: Path, scale: tuple[float, float, float], hull: bool) -> Triangles:
    """A mesh file's triangles at `scale`, or its convex hull's (read once however many bodies use it)."""
    import trimesh

    mesh: Any = trimesh.load(path, force="mesh")
    vertices = np.asarray(mesh.vertices, dtype=np.float64) * np.asarray(scale)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if not len(faces):
        return np.empty((0, 3, 3))
    return _hull(vertices) if hull else vertices[faces]


def _hull(vertices: npt.NDArray[np.float64]) -> Triangles:
    """The convex hull of `vertices` as triangles (what PyBullet collides a URDF mesh with)."""
    import trimesh

    hull: Any = trimesh.convex.convex_hull(vertices)
    return np.asarray(hull.vertices, dtype=np.float64)[np.asarray(hull.faces)]
