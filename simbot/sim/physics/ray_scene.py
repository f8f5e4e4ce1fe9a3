"""The ray engine: Intel Embree (through `embreex`) casting against the triangles of what PyBullet
collides with (`ray_shapes`).

Two structures. The static one holds every body that cannot move (a static model's links: racks,
walls, pillars, a Gazebo world's static models), placed where PyBullet holds them; it is built on
the first cast and built again only after a body enters, leaves or is teleported (`touch`). The
other holds every part of a body that moves (robots, the trolley, carts, the people's legs, dynamic
models: a link of theirs), each in its link's frame, at a slot of its own: slots lie farther apart
than any two parts' bounding spheres reach, so a ray cut to the part of it inside one part's sphere
meets no other part there. Each cast, every ray's piece inside each part's sphere is turned into
that part's link frame (where PyBullet holds the link now), moved to its slot, and all of them are
cast in one call. It is built on the first cast after a moving body enters or leaves, never while
the world runs: a scene of the moving parts posed anew each cast was measured at 14 ms for the
warehouse's people, robot and trolley, where PyBullet casts an env step's rays in 2–3 ms, and a
cast of each part's own structure at 0.5 ms in all (docs/speed.md, "The ray engine").

A ray sees every body but the one it is blind to (the lidar's own robot): it is not cast against
that body's moving parts at all, and where its first hit is on a static body it is blind to, it is
cast again from just beyond the hit, so it sees what lies behind, as PyBullet's collision masks
have it. Ranges come back as PyBullet's: the fraction of each ray to its first hit, NaN where none.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from embreex import mesh_construction, rtcore, rtcore_scene

from simbot.sim.bullet import pb
from simbot.sim.physics.body import Body
from simbot.sim.physics.ray_shapes import Part, Triangles
from simbot.transform import quaternions_to_matrices

log = logging.getLogger(__name__)

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Batch = tuple[Floats, Floats, str | None]
"""N×3 starts, N×3 ends, and the body the rays are blind to (or None)."""
BEYOND_M = 1e-4
"""How far past a hit on the blind body a ray starts again."""
PASSES = 8
"""At most this many hits on its own body a ray passes through (a lidar inside a cage of its robot)."""
MARGIN_M = 1e-3
"""How much larger than a part's farthest corner its sphere is cut at (float32's rounding of the slots)."""
GROUP_RAYS = 32
"""Consecutive rays whose bounding box is tested against every part's sphere before each ray is."""


@dataclass
class _Built:
    """An Embree scene and which body each of its geometries is."""

    scene: rtcore_scene.EmbreeScene | None
    names: list[str]
    """Each geometry's body, by geometry id."""


@dataclass(frozen=True)
class _Slotted:
    """Every moving part in one Embree scene, each in its link frame moved to its slot."""

    scene: rtcore_scene.EmbreeScene
    bodies: list[tuple[Body, list[Part]]]
    slots: Floats
    """P×3: where each part's link frame origin lies in the scene."""
    radii: Floats
    """Each part's sphere: its farthest corner, and MARGIN_M."""
    first: Ints
    """Each body's first part."""
    counts: Ints
    """Each body's parts."""


@dataclass
class RayScene:
    """The world `client`'s bodies as Embree scenes; `parts_of` gives a body's triangles (`ray_shapes`)."""

    client: int
    parts_of: Callable[[Body], list[Part]]
    _device: rtcore.EmbreeDevice = field(default_factory=rtcore.EmbreeDevice)
    _static: dict[str, Triangles] = field(default_factory=dict)
    """Each static body's triangles in the world frame."""
    _static_at: dict[str, tuple[object, ...]] = field(default_factory=dict)
    """Each static body's base pose as PyBullet held it when its triangles were placed."""
    _moving: dict[str, tuple[Body, list[Part]]] = field(default_factory=dict)
    _built: _Built | None = None
    _slotted: _Slotted | None = None

    def add(self, body: Body) -> None:
        """A body entered the world: a static one into the static structure, the others' parts into the moving one."""
        parts = self.parts_of(body)
        if body.model.static:
            self._static[body.name] = self._placed(body, parts)
            self._static_at[body.name] = self._base_pose(body)
            self._built = None
        elif parts:
            self._moving[body.name] = (body, parts)
            self._slotted = None

    def remove(self, name: str) -> None:
        if self._static.pop(name, None) is not None:
            del self._static_at[name]
            self._built = None
        if self._moving.pop(name, None) is not None:
            self._slotted = None

    def touch(self, body: Body) -> None:
        """`body` may have moved by other means than stepping (a teleport, a reset): placed again
        if it is static and did move (the structure is built again only for a change)."""
        if body.name in self._static and self._static_at[body.name] != self._base_pose(body):
            self.add(body)

    def moving_parts(self) -> int:
        return sum(len(parts) for _, parts in self._moving.values())

    def moving_build(self) -> int:
        """Builds the moving parts' structure now (a benchmark times it); returns its triangles' count."""
        self._slotted = None
        self._slotted_scene()
        return sum(len(part.triangles) for _, parts in self._moving.values() for part in parts)

    def static_build(self) -> int:
        """Builds the static structure now (a benchmark times it); returns its triangles' count."""
        self._built = None
        self._static_scene()
        return sum(len(t) for t in self._static.values())

    def cast(self, batches: Sequence[Batch]) -> list[Floats]:
        """Each batch's fractions to the first hit, NaN where none: all batches in one cast."""
        if not batches:
            return []
        starts = np.concatenate([b[0] for b in batches])
        ends = np.concatenate([b[1] for b in batches])
        names = list(dict.fromkeys(b[2] for b in batches if b[2] is not None))
        blind = np.concatenate([np.full(len(b[0]), names.index(b[2]) if b[2] else -1) for b in batches])
        static = self._cast_static(starts, ends, blind, names)
        fractions = np.fmin(static, self._cast_moving(starts, ends, blind, names, np.fmin(static, 1.0)))
        return np.split(fractions, np.cumsum([len(b[0]) for b in batches])[:-1])

    def _static_scene(self) -> _Built:
        if self._built is None:
            names = list(self._static)
            self._built = self._scene([self._static[name] for name in names], names)
        return self._built

    def _scene(self, pieces: list[Triangles], names: list[str]) -> _Built:
        """One Embree geometry a piece, each named by its body."""
        return _Built(self._embree(pieces) if pieces else None, names)

    def _embree(self, pieces: list[Triangles]) -> rtcore_scene.EmbreeScene:
        scene = rtcore_scene.EmbreeScene(self._device)
        for triangles in pieces:
            mesh_construction.TriangleMesh(scene, _f32(triangles))
        scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))  # builds it now, not in the first cast
        return scene

    def _cast_static(self, starts: Floats, ends: Floats, blind: Ints, names: list[str]) -> Floats:
        """First hits on the static bodies, passing through each ray's blind body (`blind`: its index
        in `names`, -1 for none) where that is one of them."""
        built = self._static_scene()
        fractions = np.full(len(starts), np.nan)
        if built.scene is None:
            return fractions
        span = ends - starts
        if not set(names) & set(self._static):  # no ray is blind to a static body: one pass, distances only
            tfar = built.scene.run(_f32(starts), _f32(span), dists=1.0, query="DISTANCE")
            return np.where(tfar < 1.0, tfar, np.nan)
        owners = np.array([names.index(name) if name in names else -2 for name in built.names])
        todo, travelled = np.arange(len(starts)), np.zeros(len(starts))
        length = np.linalg.norm(span, axis=1)
        for _ in range(PASSES):
            origin = starts[todo] + travelled[todo, None] * span[todo]
            hit = built.scene.run(_f32(origin), _f32(span[todo]), dists=_f32(1.0 - travelled[todo]), output=1)
            geom, tfar = hit["geomID"], hit["tfar"].astype(np.float64)
            own = (geom >= 0) & (owners[np.maximum(geom, 0)] == blind[todo])
            seen = (geom >= 0) & ~own
            fractions[todo[seen]] = travelled[todo[seen]] + tfar[seen]
            todo = todo[own]
            if not len(todo):
                break
            travelled[todo] += tfar[own] + BEYOND_M / np.maximum(length[todo], BEYOND_M)
        return fractions

    def _slotted_scene(self) -> _Slotted | None:
        """The moving parts' structure: part k's triangles in its link frame, moved to the k-th point
        of a cubic grid whose spacing is more than any two parts' spheres reach."""
        if self._slotted is None and self._moving:
            bodies = list(self._moving.values())
            parts = [part for _, body_parts in bodies for part in body_parts]
            radii = np.array([part.radius + MARGIN_M for part in parts])
            side = int(np.ceil(len(parts) ** (1.0 / 3.0) - 1e-9))
            index = np.arange(len(parts))
            grid = np.stack([index % side, index // side % side, index // (side * side)], axis=1)
            slots = (grid - (side - 1) / 2.0) * (2.0 * radii.max() + 0.1)
            triangles = np.concatenate([part.triangles + slot for part, slot in zip(parts, slots)])
            counts = np.array([len(body_parts) for _, body_parts in bodies])
            first = np.concatenate([[0], np.cumsum(counts)[:-1]])
            self._slotted = _Slotted(self._embree([triangles]), bodies, slots, radii, first, counts)
        return self._slotted

    def _cast_moving(self, starts: Floats, ends: Floats, blind: Ints, names: list[str], limit: Floats) -> Floats:
        """First hits on the moving parts before each ray's `limit` (its fraction to the static hit):
        each ray's piece inside each part's sphere (none of its blind body's), in that part's frame at
        its slot, all in one Embree call. Vectors are held as 3×N (a row a coordinate): numpy's
        loops then run along the rays, not along three coordinates."""
        fractions = np.full(len(starts), np.nan)
        slotted = self._slotted_scene()
        if slotted is None:
            return fractions
        centres, rotations = self._frames(slotted.bodies)
        origin, span = np.ascontiguousarray(starts.T), np.ascontiguousarray((ends - starts).T)
        rays, parts, enter, leave = self._crossings(slotted, origin, span, blind, names, limit, centres.T)
        if not len(rays):
            return fractions
        turned, length = np.ascontiguousarray(rotations.transpose(1, 2, 0))[:, :, parts], leave - enter
        local = _into(turned, origin[:, rays] + enter * span[:, rays] - centres.T[:, parts]) + slotted.slots.T[:, parts]
        tfar = slotted.scene.run(
            _f32(local.T), _f32(_into(turned, span[:, rays] * length).T), dists=1.0, query="DISTANCE"
        )
        hit = tfar < 1.0
        np.fmin.at(fractions, rays[hit], enter[hit] + tfar[hit] * length[hit])
        return fractions

    def _crossings(
        self,
        slotted: _Slotted,
        origin: Floats,
        span: Floats,
        blind: Ints,
        names: list[str],
        limit: Floats,
        centres: Floats,
    ) -> tuple[Ints, Ints, Floats, Floats]:
        """Each (ray, part) whose segment up to `limit` passes through the part's sphere, with where it
        enters and leaves it (fractions of the ray), none of its blind body's parts."""
        rays, parts = _grouped(origin, origin + span * limit, centres, slotted.radii)
        codes = np.repeat(
            [names.index(body.name) if body.name in names else -2 for body, _ in slotted.bodies], slotted.counts
        )
        seen = blind[rays] != codes[parts]
        rays, parts = rays[seen], parts[seen]
        enter, leave = _through(origin[:, rays], span[:, rays], centres[:, parts], slotted.radii[parts], limit[rays])
        inside = enter <= leave
        return rays[inside], parts[inside], enter[inside], leave[inside]

    def _frames(self, bodies: list[tuple[Body, list[Part]]]) -> tuple[Floats, Floats]:
        """Every moving part's link frame in the world now: positions (P×3) and rotations (P×3×3)."""
        positions, quats = [], []
        for body, parts in bodies:
            for position, quat in self._link_poses(body, [part.index for part in parts]):
                positions.append(position)
                quats.append(quat)
        return np.asarray(positions, dtype=float), quaternions_to_matrices(np.asarray(quats, dtype=float))

    def _placed(self, body: Body, parts: list[Part]) -> Triangles:
        """A body's triangles where PyBullet holds it now."""
        frames = self._link_frames(body, [part.index for part in parts])
        placed = [part.triangles @ rotation.T + position for part, (position, rotation) in zip(parts, frames)]
        return np.concatenate(placed) if placed else np.empty((0, 3, 3))

    def _base_pose(self, body: Body) -> tuple[object, ...]:
        return tuple(pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client))

    def _link_frames(self, body: Body, indices: list[int]) -> list[tuple[Floats, Floats]]:
        """The world pose (position, rotation matrix) of each link's URDF frame, as PyBullet holds it."""
        poses = self._link_poses(body, indices)
        if not poses:
            return []
        rotations = quaternions_to_matrices(np.asarray([quat for _, quat in poses], dtype=float))
        return list(zip(np.asarray([position for position, _ in poses], dtype=float), rotations))

    def _link_poses(self, body: Body, indices: list[int]) -> list[tuple[Sequence[float], Sequence[float]]]:
        """The world pose (position, quaternion) of each link's URDF frame, as PyBullet's collision
        holds it since the last step (forward kinematics are not run again: that rewrites PyBullet's
        cached link transforms and moves the next step's last bits)."""
        links = [i for i in indices if i >= 0]
        states = iter(pb.getLinkStates(body.id, links, physicsClientId=self.client) if links else [])
        poses = []
        for index in indices:
            if index < 0:
                com = pb.getBasePositionAndOrientation(body.id, physicsClientId=self.client)
                poses.append(pb.multiplyTransforms(*com, *body.com_to_root))
            else:
                state = next(states)
                poses.append((state[4], state[5]))
        return poses


def _grouped(origin: Floats, reached: Floats, centres: Floats, radii: Floats) -> tuple[Ints, Ints]:
    """(ray, part) pairs to test exactly: every ray of each run of GROUP_RAYS consecutive rays (a
    lidar's are neighbours) whose bounding box reaches a part's sphere, with that part."""
    n = origin.shape[1]
    heads = np.arange(0, n, GROUP_RAYS)
    low = np.minimum.reduceat(np.minimum(origin, reached), heads, axis=1)[:, :, None]
    high = np.maximum.reduceat(np.maximum(origin, reached), heads, axis=1)[:, :, None]
    gap = np.maximum(low - centres[:, None, :], 0.0) + np.maximum(centres[:, None, :] - high, 0.0)
    group, parts = np.nonzero(_dot3(gap, gap) <= radii * radii)
    sizes = np.minimum(GROUP_RAYS, n - heads[group])
    rays = np.repeat(heads[group] - np.cumsum(sizes) + sizes, sizes) + np.arange(int(sizes.sum()))
    return rays, np.repeat(parts, sizes)


def _through(starts: Floats, span: Floats, centres: Floats, radii: Floats, limit: Floats) -> tuple[Floats, Floats]:
    """Where each segment start + t·span (t in [0, limit]) enters and leaves each sphere (vectors 3×…,
    broadcast elementwise); it enters after it leaves where it misses the sphere."""
    rel = starts - centres
    a, b = np.maximum(_dot3(span, span), 1e-300), _dot3(span, rel)
    disc = b * b - a * (_dot3(rel, rel) - radii * radii)
    root = np.sqrt(np.maximum(disc, 0.0))
    enter = np.maximum((-b - root) / a, 0.0)
    leave = np.where(disc >= 0.0, np.minimum((-b + root) / a, limit), -1.0)
    return enter, leave


def _dot3(a: Floats, b: Floats) -> Floats:
    """Dot products of 3-vectors held as 3×…, summed in order (no BLAS)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _into(rotations: Floats, vectors: Floats) -> Floats:
    """Each vector (3×M) turned into its frame (rotations 3×3×M): rotationᵀ · vector, summed in order."""
    return rotations[0] * vectors[0] + rotations[1] * vectors[1] + rotations[2] * vectors[2]


def _f32(values: Floats) -> npt.NDArray[np.float32]:
    return np.ascontiguousarray(values, dtype=np.float32)
