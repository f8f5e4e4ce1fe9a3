"""The ray engine: Intel Embree (`embree`) casting against the triangles of what PyBullet collides
with (`ray_shapes`).

One scene of two parts. The static part is every body that cannot move (a static model's links:
racks, walls, pillars, a Gazebo world's static models), placed where PyBullet holds them, one mesh a
body. The moving part is an array of instances, one a part of a body that moves (a link of a robot,
the trolley, a cart, a person's legs, a dynamic model), each of a scene of that part's triangles in
its link frame, built once and shared by every part of the same shape (a hundred tugs: three
scenes). The scene is built on the first cast, and again only after a body enters or leaves or a
static one is teleported (`touch`). Each cast writes every part's link pose as PyBullet holds it
into the array's transforms and commits it: Embree builds the instances' small structure again and
keeps the static meshes' (docs/speed.md, "The ray engine").

A ray sees every body but the one it is blind to (the lidar's own robot): where its first hit is on
that body, it is cast again from just beyond the hit, so it sees what lies behind, as PyBullet's
collision masks have it. Ranges come back as PyBullet's: the fraction of each ray to its first hit,
NaN where none.
"""

from __future__ import annotations

import ctypes
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from simbot.sim.bullet import pb
from simbot.sim.physics import embree
from simbot.sim.physics.body import Body
from simbot.sim.physics.ray_shapes import Part, Triangles
from simbot.transform import quaternions_to_matrices

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Batch = tuple[Floats, Floats, str | None]
"""N×3 starts, N×3 ends, and the body the rays are blind to (or None)."""
BEYOND_M = 1e-4
"""How far past a hit on the blind body a ray starts again."""
PASSES = 8
"""At most this many hits on its own body a ray passes through (a lidar inside a cage of its robot)."""
NOT_BLIND = -2
"""The code of a body no ray of a cast is blind to."""
CODES_KEPT = 64
"""Sets of blind bodies whose codes are kept (a fleet's lidars fall due in a few sets)."""


@dataclass
class _Top:
    """The scene every ray is cast in: the static bodies' scene, instanced once, and the moving parts' array."""

    scene: embree.Scene
    static_id: int
    """The static scene's instance id (-1: none)."""
    static_names: list[str]
    """Each static mesh's body, by geometry id."""
    array: embree.InstanceArray | None
    bodies: list[tuple[Body, list[Part]]]
    owners: list[str]
    """Each instance's body."""
    _codes: dict[tuple[str, ...], tuple[Ints, Ints]] = field(default_factory=dict)

    def codes(self, names: list[str]) -> tuple[Ints, Ints]:
        """Each static mesh's and each instance's body as its index in `names` (NOT_BLIND where it
        is not there), and one NOT_BLIND more, which a miss (-1) reads; kept for the next cast."""
        key = tuple(names)
        if key not in self._codes:
            if len(self._codes) >= CODES_KEPT:
                self._codes.clear()
            index = {name: k for k, name in enumerate(names)}
            self._codes[key] = tuple(  # type: ignore[assignment]
                np.array([index.get(owner, NOT_BLIND) for owner in owners] + [NOT_BLIND])
                for owners in (self.static_names, self.owners)
            )
        return self._codes[key]


@dataclass
class RayScene:
    """The world `client`'s bodies as one Embree scene; `parts_of` gives a body's triangles (`ray_shapes`)."""

    client: int
    parts_of: Callable[[Body], list[Part]]
    lib: ctypes.CDLL
    """Embree's library (`embree.library()`)."""
    _device: embree.Device = field(init=False)
    _static: dict[str, Triangles] = field(default_factory=dict)
    """Each static body's triangles in the world frame."""
    _static_at: dict[str, tuple[object, ...]] = field(default_factory=dict)
    """Each static body's base pose as PyBullet held it when its triangles were placed."""
    _static_scene: embree.Scene | None = None
    _moving: dict[str, tuple[Body, list[Part]]] = field(default_factory=dict)
    _shapes: dict[bytes, embree.Scene] = field(default_factory=dict)
    """Each part shape's scene, by its triangles' digest."""
    _shapes_of: dict[str, list[embree.Scene]] = field(default_factory=dict)
    """Each moving body's parts' scenes, found when it entered (its triangles hashed once)."""
    _top: _Top | None = None

    def __post_init__(self) -> None:
        self._device = embree.Device(self.lib)

    def add(self, body: Body) -> None:
        """A body entered the world: a static one into the static scene, the others' parts into the array."""
        parts = self.parts_of(body)
        if body.model.static:
            self._static[body.name] = self._placed(body, parts)
            self._static_at[body.name] = self._base_pose(body)
            self._static_scene = self._top = None
        elif parts:
            self._moving[body.name] = (body, parts)
            self._shapes_of[body.name] = [self._shape(part) for part in parts]
            self._top = None

    def remove(self, name: str) -> None:
        if self._static.pop(name, None) is not None:
            del self._static_at[name]
            self._static_scene = self._top = None
        if self._moving.pop(name, None) is not None:
            del self._shapes_of[name]
            self._top = None

    def touch(self, body: Body) -> None:
        """`body` may have moved by other means than stepping (a teleport, a reset): placed again
        if it is static and did move (the scene is built again only for a change)."""
        if body.name in self._static and self._static_at[body.name] != self._base_pose(body):
            self.add(body)

    def moving_build(self) -> int:
        """Builds the moving parts' scenes and array now, as a body entering a new world costs (a
        benchmark times it); returns their triangles' count."""
        self._shapes.clear()
        self._shapes_of = {name: [self._shape(part) for part in parts] for name, (_, parts) in self._moving.items()}
        self._top = None
        self._top_scene()
        return sum(len(part.triangles) for _, parts in self._moving.values() for part in parts)

    def static_build(self) -> int:
        """Builds the static scene now (a benchmark times it); returns its triangles' count."""
        self._static_scene = self._top = None
        self._top_scene()
        return sum(len(t) for t in self._static.values())

    def cast(self, batches: Sequence[Batch]) -> list[Floats]:
        """Each batch's fractions to the first hit, NaN where none: all batches in one cast."""
        if not batches:
            return []
        starts = np.concatenate([b[0] for b in batches])
        span = np.concatenate([b[1] for b in batches]) - starts
        names = list(dict.fromkeys(b[2] for b in batches if b[2] is not None))
        sizes = [len(b[0]) for b in batches]
        blind = np.repeat([names.index(b[2]) if b[2] else -1 for b in batches], sizes)
        top = self._top_scene()
        if top.array is not None:
            top.array.pose(self._poses(top.bodies))
            top.scene.commit()
        fractions = self._first_hits(top, starts, span, blind, names)
        return np.split(fractions, np.cumsum(sizes)[:-1])

    def _first_hits(self, top: _Top, starts: Floats, span: Floats, blind: Ints, names: list[str]) -> Floats:
        """Each ray's first hit on a body it is not blind to (`blind`: its index in `names`, -1 for
        none), cast again from beyond each hit on its blind body (at most PASSES times)."""
        hits = embree.cast(top.scene, starts, span, 0.0, 1.0)
        fractions = hits.t
        todo = np.flatnonzero(self._owners(top, hits, names) == blind)
        for _ in range(PASSES):
            if not len(todo):
                break
            length = np.sqrt(np.sum(span[todo] ** 2, axis=1))
            hits = embree.cast(
                top.scene, starts[todo], span[todo], fractions[todo] + BEYOND_M / np.maximum(length, BEYOND_M), 1.0
            )
            fractions[todo] = hits.t
            todo = todo[self._owners(top, hits, names) == blind[todo]]
        fractions[todo] = np.nan
        return fractions

    @staticmethod
    def _owners(top: _Top, hits: embree.Hits, names: list[str]) -> Ints:
        """The body each ray hit, as its index in `names` (NOT_BLIND for another body or none)."""
        static_codes, part_codes = top.codes(names)
        return np.where(
            hits.instance == top.static_id,
            static_codes[np.minimum(hits.geometry, len(static_codes) - 1)],
            part_codes[np.minimum(hits.index, len(part_codes) - 1)],
        )

    def _top_scene(self) -> _Top:
        """The scene, built anew after a body entered or left or a static one was moved: the static
        part instanced once, then the array of every moving part."""
        if self._top is None:
            scene = embree.Scene(self._device)
            static_names = list(self._static)
            static_id = scene.instance(self._static_part(static_names)) if static_names else -1
            bodies = list(self._moving.values())
            shapes = [shape for body, _ in bodies for shape in self._shapes_of[body.name]]
            array = None
            if shapes:
                unique = list({id(shape): shape for shape in shapes}.values())
                array = scene.instance_array(unique, [unique.index(shape) for shape in shapes])
            owners = [body.name for body, body_parts in bodies for _ in body_parts]
            scene.commit()
            self._top = _Top(scene, static_id, static_names, array, bodies, owners)
        return self._top

    def _static_part(self, names: list[str]) -> embree.Scene:
        """The static bodies' meshes in a scene of their own (geometry ids in `names`' order): in the
        scene the rays are cast in, committing the moving parts would build them again (measured:
        1 ms, where the warehouse's env step casts in 0.4)."""
        if self._static_scene is None:
            scene = embree.Scene(self._device)
            for name in names:
                scene.triangles(self._static[name])
            scene.commit()
            self._static_scene = scene
        return self._static_scene

    def _shape(self, part: Part) -> embree.Scene:
        """The scene of a part's triangles in its link frame, shared by every part of that shape."""
        key = hashlib.blake2b(np.ascontiguousarray(part.triangles).tobytes(), digest_size=16).digest()
        if key not in self._shapes:
            scene = embree.Scene(self._device)
            scene.triangles(part.triangles)
            scene.commit()
            self._shapes[key] = scene
        return self._shapes[key]

    def _poses(self, bodies: list[tuple[Body, list[Part]]]) -> Floats:
        """Every moving part's link frame in the world now: P rows of a position and a quaternion (x, y, z, w)."""
        return np.array(
            [
                (*position, *quat)
                for body, parts in bodies
                for position, quat in self._link_poses(body, [part.index for part in parts])
            ],
            dtype=float,
        )

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
