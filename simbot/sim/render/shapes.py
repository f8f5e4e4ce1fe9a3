"""Triangles for the OpenGL renderer: each visual shape PyBullet reports, tessellated in its link
frame as a triangle soup of positions and normals (float32, N×3 each, three rows a triangle)."""

from __future__ import annotations

import logging
from functools import cache
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render.scene import VisualShape
from simbot.transform import Transform

log = logging.getLogger(__name__)

Array = npt.NDArray[np.float32]
SEGMENTS = 32
"""Around a cylinder, sphere or capsule: at 640×480 a 2 m pillar shows no facets at 1 m."""
PLANE_HALF_SIZE = 100.0
"""A plane visual is drawn as a square this many metres each side of its origin."""

GEOM_SPHERE, GEOM_BOX, GEOM_CYLINDER, GEOM_MESH, GEOM_PLANE, GEOM_CAPSULE = 2, 3, 4, 5, 6, 7
"""PyBullet's geometry type numbers (pybullet.GEOM_*), fixed in its C API."""


def triangles(shape: VisualShape) -> tuple[Array, Array]:
    """(positions, normals) of the shape in its link frame; empty arrays for a shape with no surface."""
    positions, normals = _local(shape)
    local = Transform.of(*shape.local).matrix()
    rotation = local[:3, :3]
    placed = positions @ rotation.T + local[:3, 3]
    return placed.astype(np.float32), (normals @ rotation.T).astype(np.float32)


def _local(shape: VisualShape) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    dims = shape.dimensions
    if shape.geometry == GEOM_BOX:
        return box(np.asarray(dims[:3]) / 2.0)
    if shape.geometry == GEOM_SPHERE:
        return revolved(_sphere_profile(dims[0], 0.0))
    if shape.geometry == GEOM_CYLINDER:
        return revolved(_cylinder_profile(dims[0], dims[1]))
    if shape.geometry == GEOM_CAPSULE:
        return revolved(_sphere_profile(dims[1], dims[0] / 2.0))
    if shape.geometry == GEOM_PLANE:
        return box(np.array([PLANE_HALF_SIZE, PLANE_HALF_SIZE, 0.0]))
    if shape.geometry == GEOM_MESH:
        return mesh(shape.mesh, tuple(dims[:3]))
    log.warning("visual of link %d: geometry type %d is not drawn", shape.link, shape.geometry)
    return np.zeros((0, 3)), np.zeros((0, 3))


_FACES = [(axis, sign) for axis in range(3) for sign in (1.0, -1.0)]


def box(half: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Twelve triangles, flat normals, centred on the origin."""
    positions: list[npt.NDArray[np.float64]] = []
    normals: list[npt.NDArray[np.float64]] = []
    for axis, sign in _FACES:
        u, v = (axis + 1) % 3, (axis + 2) % 3
        corners = []
        for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            corner = np.zeros(3)
            corner[axis], corner[u], corner[v] = sign * half[axis], cu * half[u], cv * half[v]
            corners.append(corner)
        positions += [corners[i] for i in (0, 1, 2, 0, 2, 3)]
        normal = np.zeros(3)
        normal[axis] = sign
        normals += [normal] * 6
    return np.asarray(positions), np.asarray(normals)


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


def revolved(
    profile: list[tuple[float, float, float, float]],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A surface of revolution about z: each pair of profile points sweeps a band of quads."""
    angles = np.linspace(0.0, 2.0 * np.pi, SEGMENTS + 1)
    cos, sin = np.cos(angles), np.sin(angles)
    positions: list[npt.NDArray[np.float64]] = []
    normals: list[npt.NDArray[np.float64]] = []
    for (r0, z0, nr0, nz0), (r1, z1, nr1, nz1) in zip(profile, profile[1:], strict=False):
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
    return np.asarray(positions), np.asarray(normals)


def mesh(path: str, scale: tuple[float, ...]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A mesh file's triangles, scaled, with flat face normals; nothing (and a warning) when it cannot be read."""
    positions, normals = _mesh_file(path)
    return positions * np.asarray(scale), normals * np.sign(np.prod(scale))


@cache
def _mesh_file(path: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    import trimesh  # yourdfpy's dependency: STL, OBJ, PLY, glTF

    try:
        loaded: Any = trimesh.load(path, force="mesh")
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
        log.warning("mesh %s cannot be read (%s); it is not drawn", path, exc)
        return np.zeros((0, 3)), np.zeros((0, 3))
    faces = np.asarray(loaded.faces)
    positions = np.asarray(loaded.vertices, dtype=np.float64)[faces].reshape(-1, 3)
    normals = np.repeat(np.asarray(loaded.face_normals, dtype=np.float64), 3, axis=0)
    return positions, normals
