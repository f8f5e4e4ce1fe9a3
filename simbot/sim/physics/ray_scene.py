"""The ray engine: Intel Embree (through `embreex`) casting against the triangles of what PyBullet
collides with (`ray_shapes`).

Two structures. The static one holds every body that cannot move (a static model's links: racks,
walls, pillars, a Gazebo world's static models), placed where PyBullet holds them; it is built on
the first cast and built again only after a body enters, leaves or is teleported (`touch`). Every
part of a body that moves (robots, the trolley, carts, the people's legs, dynamic models: a link
of theirs) is a small structure of its own, built once in its link's frame; each cast, the rays
that pass within a part's bounding sphere are turned into its link's frame, where PyBullet holds
the link now, and cast against it. Nothing is built while the world runs: building a scene of the
moving parts each cast was measured at 14 ms for the warehouse's people, robot and trolley, where
PyBullet casts an env step's rays in 2–3 ms (docs/speed.md, "The ray engine").

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


@dataclass
class _Built:
    """An Embree scene and which body each of its geometries is."""

    scene: rtcore_scene.EmbreeScene | None
    names: list[str]
    """Each geometry's body, by geometry id."""


@dataclass(frozen=True)
class _Local:
    """A moving body's part and its structure, in the part's link frame."""

    part: Part
    scene: rtcore_scene.EmbreeScene


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
    _moving: dict[str, tuple[Body, list[_Local]]] = field(default_factory=dict)
    _built: _Built | None = None

    def add(self, body: Body) -> None:
        """A body entered the world: a static one into the static structure, each part of the others its own."""
        parts = self.parts_of(body)
        if body.model.static:
            self._static[body.name] = self._placed(body, parts)
            self._static_at[body.name] = self._base_pose(body)
            self._built = None
        elif parts:
            self._moving[body.name] = (body, [_Local(part, self._embree([part.triangles])) for part in parts])

    def remove(self, name: str) -> None:
        if self._static.pop(name, None) is not None:
            del self._static_at[name]
            self._built = None
        self._moving.pop(name, None)

    def touch(self, body: Body) -> None:
        """`body` may have moved by other means than stepping (a teleport, a reset): placed again
        if it is static and did move (the structure is built again only for a change)."""
        if body.name in self._static and self._static_at[body.name] != self._base_pose(body):
            self.add(body)

    def moving_parts(self) -> int:
        return sum(len(parts) for _, parts in self._moving.values())

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
        fractions = np.fmin(
            self._cast_static(starts, ends, blind, names), self._cast_moving(starts, ends, blind, names)
        )
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

    def _cast_moving(self, starts: Floats, ends: Floats, blind: Ints, names: list[str]) -> Floats:
        """First hits on the moving parts, each ray cast only against the parts it passes near (the
        bodies' bounding spheres first, then their parts'), none against its blind body's."""
        fractions = np.full(len(starts), np.nan)
        if not self._moving:
            return fractions
        bodies = list(self._moving.values())
        counts = np.array([len(parts) for _, parts in bodies])
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        centres, rotations = self._frames(bodies)
        radii = np.array([local.part.radius for _, parts in bodies for local in parts])
        middles = np.add.reduceat(centres, first, axis=0) / counts[:, None]
        reach = np.maximum.reduceat(np.linalg.norm(centres - np.repeat(middles, counts, axis=0), axis=1) + radii, first)
        span = ends - starts
        near = _near(starts, span, middles, reach)
        codes = np.array([names.index(body.name) if body.name in names else -2 for body, _ in bodies])
        near &= blind[:, None] != codes[None, :]
        for b in np.flatnonzero(near.any(axis=0)):
            rays, parts = np.flatnonzero(near[:, b]), slice(first[b], first[b] + counts[b])
            close = (
                _near(starts[rays], span[rays], centres[parts], radii[parts]) if counts[b] > 1 else near[rays][:, [b]]
            )
            for column in np.flatnonzero(close.any(axis=0)):
                hits, at = rays[close[:, column]], first[b] + column
                tfar = bodies[b][1][column].scene.run(
                    _f32((starts[hits] - centres[at]) @ rotations[at]), _f32(span[hits] @ rotations[at]),
                    dists=1.0, query="DISTANCE",
                )  # fmt: skip
                fractions[hits] = np.fmin(fractions[hits], np.where(tfar < 1.0, tfar, np.nan))
        return fractions

    def _frames(self, bodies: list[tuple[Body, list[_Local]]]) -> tuple[Floats, Floats]:
        """Every moving part's link frame in the world now: positions (P×3) and rotations (P×3×3)."""
        positions, quats = [], []
        for body, parts in bodies:
            for position, quat in self._link_poses(body, [local.part.index for local in parts]):
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


def _near(starts: Floats, span: Floats, centres: Floats, radii: Floats) -> npt.NDArray[np.bool_]:
    """Rays × spheres: whether each ray's segment passes within each sphere (closest approach, as matrices)."""
    length2 = np.einsum("ij,ij->i", span, span)[:, None]
    along = span @ centres.T - np.einsum("ij,ij->i", span, starts)[:, None]  # (c − s)·d, d unnormalised
    t = np.clip(along, 0.0, length2)
    gap2 = (
        np.einsum("ij,ij->i", starts, starts)[:, None] + np.einsum("ij,ij->i", centres, centres)[None, :]
        - 2.0 * (starts @ centres.T) - (2.0 * along - t) * t / np.maximum(length2, 1e-300)
    )  # fmt: skip
    return gap2 <= (radii * radii)[None, :]


def _f32(values: Floats) -> npt.NDArray[np.float32]:
    return np.ascontiguousarray(values, dtype=np.float32)
