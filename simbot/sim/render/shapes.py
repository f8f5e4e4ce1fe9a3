"""Triangles for the OpenGL renderer: each visual shape, tessellated in its link frame as a
triangle soup of positions, normals and texture coordinates (N×3, N×3, N×2, three rows a triangle).

Texture coordinates follow Gazebo's primitives: each face of a box shows the whole image, upright
on the side faces and not mirrored seen from outside; a plane shows it once; a cylinder, sphere or
capsule wraps it once around (u) and from the bottom to the top along the surface (v, by arc
length: a sphere's v is its latitude; a cylinder's caps take the ends of the image, where Gazebo
maps them flat)."""

from __future__ import annotations

import functools
import logging

import numpy as np
import numpy.typing as npt

log = logging.getLogger(__name__)

Array = npt.NDArray[np.float32]
SEGMENTS = 32
"""Around a cylinder, sphere or capsule: at 640×480 a 2 m pillar shows no facets at 1 m."""
PLANE_HALF_SIZE = 100.0
"""A plane visual is drawn as a square this many metres each side of its origin."""

GEOM_SPHERE, GEOM_BOX, GEOM_CYLINDER, GEOM_MESH, GEOM_PLANE, GEOM_CAPSULE = 2, 3, 4, 5, 6, 7
"""PyBullet's geometry type numbers (pybullet.GEOM_*), fixed in its C API."""


Tessellated = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]
"""Positions, normals, texture coordinates."""


@functools.lru_cache(maxsize=4096)
def primitive(geometry: int, dims: tuple[float, ...]) -> Tessellated | None:
    """A primitive centred on its origin, sized as PyBullet reports a visual shape (box: full size; sphere: radius; cylinder and capsule: length, radius);
    None for a mesh or an unknown type. Made once for each shape and size (a world repeats them,
    an edit re-reads them); its arrays are read-only."""
    made = _made(geometry, dims)
    if made is not None:
        for array in made:
            array.flags.writeable = False
    return made


def _made(geometry: int, dims: tuple[float, ...]) -> Tessellated | None:
    if geometry == GEOM_BOX:
        return box(np.asarray(dims[:3]) / 2.0)
    if geometry == GEOM_SPHERE:
        return revolved(_sphere_profile(dims[0], 0.0))
    if geometry == GEOM_CYLINDER:
        return revolved(_cylinder_profile(dims[0], dims[1]))
    if geometry == GEOM_CAPSULE:
        return revolved(_sphere_profile(dims[1], dims[0] / 2.0))
    if geometry == GEOM_PLANE:
        return box(np.array([PLANE_HALF_SIZE, PLANE_HALF_SIZE, 0.0]))
    return None


_FACES = [(axis, sign) for axis in range(3) for sign in (1.0, -1.0)]
_IMAGE_AXES = {
    (0, 1.0): ((1, 1.0), (2, 1.0)),
    (0, -1.0): ((1, -1.0), (2, 1.0)),
    (1, 1.0): ((0, -1.0), (2, 1.0)),
    (1, -1.0): ((0, 1.0), (2, 1.0)),
    (2, 1.0): ((0, 1.0), (1, 1.0)),
    (2, -1.0): ((0, 1.0), (1, -1.0)),
}
"""Each face's (axis, direction) of the image's u and v: u × v is the face's outward normal, so
the image reads unmirrored from outside, and v is up (+z) on the side faces."""


def box(half: npt.NDArray[np.float64]) -> Tessellated:
    """Twelve triangles, flat normals, centred on the origin; each face the whole image."""
    positions: list[npt.NDArray[np.float64]] = []
    normals: list[npt.NDArray[np.float64]] = []
    uvs: list[tuple[float, float]] = []
    for axis, sign in _FACES:
        u, v = (axis + 1) % 3, (axis + 2) % 3
        corners = []
        for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            corner = np.zeros(3)
            corner[axis], corner[u], corner[v] = sign * half[axis], cu * half[u], cv * half[v]
            corners.append(corner)
        face = [corners[i] for i in (0, 1, 2, 0, 2, 3)]
        (image_u, sign_u), (image_v, sign_v) = _IMAGE_AXES[(axis, sign)]
        uvs += [(_unit(sign_u * c[image_u], half[image_u]), _unit(sign_v * c[image_v], half[image_v])) for c in face]
        positions += face
        normal = np.zeros(3)
        normal[axis] = sign
        normals += [normal] * 6
    return np.asarray(positions), np.asarray(normals), np.asarray(uvs)


def _unit(coordinate: float, half: float) -> float:
    """-half..half as 0..1 (0.5 across a side of no size)."""
    return 0.5 + coordinate / (2.0 * half) if half > 0 else 0.5


def _sphere_profile(radius: float, half_length: float) -> list[tuple[float, float, float, float]]:
    """(r, z, normal r, normal z) from the bottom pole to the top pole; a capsule when half_length > 0."""
    rings = SEGMENTS // 2
    profile = []
    for i in range(rings + 1):
        polar = np.pi * i / rings - np.pi / 2.0  # -90° .. 90°
        offset = half_length if polar > 0 or (polar == 0 and half_length == 0) else -half_length
        nr, nz = np.cos(polar), np.sin(polar)
        profile.append((radius * nr, radius * nz + offset, nr, nz))
        if polar == 0 and half_length > 0:
            profile.append((radius, half_length, 1.0, 0.0))
    return profile


def _cylinder_profile(length: float, radius: float) -> list[tuple[float, float, float, float]]:
    """Flat caps (their own normals) and a smooth side."""
    h = length / 2.0
    return [
        (0.0, -h, 0.0, -1.0),
        (radius, -h, 0.0, -1.0),
        (radius, -h, 1.0, 0.0),
        (radius, h, 1.0, 0.0),
        (radius, h, 0.0, 1.0),
        (0.0, h, 0.0, 1.0),
    ]


def revolved(profile: list[tuple[float, float, float, float]]) -> Tessellated:
    """A surface of revolution about z: each pair of profile points sweeps a band of quads; u
    runs around, v along the profile by arc length."""
    angles = np.linspace(0.0, 2.0 * np.pi, SEGMENTS + 1)
    cos, sin = np.cos(angles), np.sin(angles)
    steps = np.hypot(np.diff([p[0] for p in profile]), np.diff([p[1] for p in profile]))
    arc = np.concatenate([[0.0], np.cumsum(steps)]) / max(float(steps.sum()), 1e-12)
    u = angles / (2.0 * np.pi)
    positions: list[npt.NDArray[np.float64]] = []
    normals: list[npt.NDArray[np.float64]] = []
    uvs: list[tuple[float, float]] = []
    for i, ((r0, z0, nr0, nz0), (r1, z1, nr1, nz1)) in enumerate(zip(profile, profile[1:], strict=False)):
        if r0 == r1 == 0.0 or (r0 == r1 and z0 == z1):
            continue  # a degenerate band: the pole, or the seam between a cap and the side
        ring0 = np.stack([r0 * cos, r0 * sin, np.full_like(cos, z0)], axis=1)
        ring1 = np.stack([r1 * cos, r1 * sin, np.full_like(cos, z1)], axis=1)
        n0 = np.stack([nr0 * cos, nr0 * sin, np.full_like(cos, nz0)], axis=1)
        n1 = np.stack([nr1 * cos, nr1 * sin, np.full_like(cos, nz1)], axis=1)
        for k in range(SEGMENTS):
            quad_p = (ring0[k], ring0[k + 1], ring1[k + 1], ring0[k], ring1[k + 1], ring1[k])
            quad_n = (n0[k], n0[k + 1], n1[k + 1], n0[k], n1[k + 1], n1[k])
            positions += quad_p
            normals += quad_n
            v0, v1 = arc[i], arc[i + 1]
            uvs += [(u[k], v0), (u[k + 1], v0), (u[k + 1], v1), (u[k], v0), (u[k + 1], v1), (u[k], v1)]
    return np.asarray(positions), np.asarray(normals), np.asarray(uvs)
