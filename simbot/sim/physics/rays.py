"""Rays cast in the world, each robot's ray sensors blind to the robot itself: through the ray engine
(`ray_scene`, Intel Embree) where `embreex` is installed, else through PyBullet's `rayTestBatch`.

Both give the same ranges, within a centimetre (tests/test_ray_engine.py). The engine is blind to
a body by casting again from beyond each hit on it; PyBullet by collision groups, of which there
are enough for 210 robots (`ray_groups`). `SIMBOT_RAYS=pybullet` (or `Physics(ray_engine=False)`)
asks for PyBullet's cast where the engine is installed.
"""

from __future__ import annotations

import functools
import itertools
import logging
import os
import platform
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from pathlib import Path

import numpy as np
import numpy.typing as npt

from simbot.sim.bullet import pb
from simbot.sim.physics import embree
from simbot.sim.physics.body import Body
from simbot.sim.physics.ray_scene import RayScene
from simbot.sim.physics.ray_shapes import body_parts

log = logging.getLogger(__name__)

RAYS_VARIABLE = "SIMBOT_RAYS"
"""`pybullet` casts every ray through PyBullet even where the engine is installed."""
Batch = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], "Body | None"]
"""N×3 starts, N×3 ends, and the body the rays pass through (or None)."""

RAY_GROUP_BITS = range(10, 31)
"""Collision-group bits that tell robots apart for rays. PyBullet's own groups are 1 (dynamic) and
2 (static), Bullet's up to 32 (bit 5); a body in groups of these bits alone, with mask −1, still
collides with all."""


def ray_groups() -> Iterator[int]:
    """Each robot's ray group: two bits of RAY_GROUP_BITS, a pair no other robot has (210 robots).
    No pair holds another, so a ray mask that clears one robot's bits keeps a bit of every other's:
    a sensor is blind to its own robot and sees every other one. As cheap as dropping hits on the own
    body from rayTestBatch's results (measured: the same for 720 rays among ten tugs) and exact, where
    a dropped hit would hide whatever lies beyond it."""
    return ((1 << a) | (1 << b) for a, b in itertools.combinations(RAY_GROUP_BITS, 2))


def engine_wanted() -> bool:
    """Whether the environment leaves the engine on (`SIMBOT_RAYS` is not `pybullet`)."""
    return os.environ.get(RAYS_VARIABLE, "").strip().lower() != "pybullet"


@dataclass
class Rays:
    """Casting in the world `client`: through the engine where it is wanted and installed, else PyBullet."""

    client: int
    folder: Path
    """Where meshes generated for the engine's triangles go (the loader's URDF folder)."""
    engine: bool
    bullet: BulletRays = field(init=False)
    scene: RayScene | None = field(init=False)

    def __post_init__(self) -> None:
        self.bullet = BulletRays(self.client)
        self.scene = _engine(self.client, self.folder) if self.engine else None

    def add(self, body: Body) -> None:
        if self.scene is not None:
            self.scene.add(body)

    def remove(self, name: str) -> None:
        """A removed body: out of the engine's scenes, its ray group free for the next robot."""
        if self.scene is not None:
            self.scene.remove(name)
        self.bullet.release(name)

    def moved(self, bodies: Sequence[Body]) -> None:
        """`bodies` may have moved by other means than stepping (a teleport, a reset)."""
        if self.scene is not None:
            for body in bodies:
                self.scene.touch(body)

    def blind_to(self, body: Body) -> None:
        """Prepares rays blind to `body`: PyBullet's cast needs a ray group, set before stepping (the
        engine needs none, so where the groups run out the engine alone casts for it)."""
        try:
            self.bullet.blind_to(body)
        except ValueError:
            if self.scene is None:
                raise

    def cast(self, batches: Sequence[Batch]) -> list[npt.NDArray[np.float64]]:
        """Each batch's fraction of each ray to its first hit, NaN where it hits nothing; every batch
        in one cast: the engine's, or PyBullet's where the engine is off."""
        if self.scene is not None:
            return self.scene.cast([(starts, ends, body.name if body else None) for starts, ends, body in batches])
        return self.bullet.cast_all(batches)


def _engine(client: int, folder: Path) -> RayScene | None:
    """The ray engine of the world `client`, or None where embreex is not installed."""
    lib = embree.library() if embree_installed() else None
    return RayScene(client, lambda body: body_parts(body, folder), lib) if lib is not None else None


@functools.cache
def embree_installed() -> bool:
    """Whether Embree's library (the embreex wheel's) loads; where not, one logged line a process says so."""
    if embree.library() is None:
        log.warning(
            "ray engine: embreex (Intel Embree) is not installed (it has no wheel for %s %s): lidars cast through PyBullet",
            platform.system(), platform.machine(),
        )  # fmt: skip
        return False
    return True


@dataclass
class BulletRays:
    """PyBullet's cast: the ray groups handed out in the world `client`, and `rayTestBatch`."""

    client: int
    _groups: dict[str, int] = field(default_factory=dict)
    _free: Iterator[int] = field(default_factory=ray_groups)
    _returned: list[int] = field(default_factory=list)
    """Groups of removed models, handed out again first (lowest first: the same world, the same groups)."""

    def blind_to(self, body: Body) -> int:
        """`body`'s ray group, given to it on the first call."""
        group = self._groups.get(body.name)
        if group is None:
            group = self._returned.pop(0) if self._returned else next(self._free, None)
            if group is None:
                raise ValueError(f"model {body.name!r}: more robots carry ray sensors than there are ray groups")
            for index in body.indices:  # in index order: Bullet re-adds the proxies in it
                pb.setCollisionFilterGroupMask(body.id, index, group, -1, physicsClientId=self.client)
            self._groups[body.name] = group
        return group

    def release(self, name: str) -> None:
        """A removed body's group, free for the next robot."""
        if (group := self._groups.pop(name, None)) is not None:
            self._returned = sorted([*self._returned, group])

    def cast_all(self, batches: Sequence[Batch]) -> list[npt.NDArray[np.float64]]:
        """`cast` of each batch, blind to its body (given a ray group now if it has none)."""
        return [self.cast(starts, ends, ~self.blind_to(body) if body else -1) for starts, ends, body in batches]

    def cast(
        self, starts: npt.NDArray[np.float64], ends: npt.NDArray[np.float64], mask: int
    ) -> npt.NDArray[np.float64]:
        """Fraction of each ray to its first hit among the bodies `mask` sees, NaN where it hits
        nothing. Cast in batches under PyBullet's most (a 3-D lidar casts more): it refuses more
        than 16384 rays and answers exactly 16384 with one result short."""
        batch = pb.MAX_RAY_INTERSECTION_BATCH_SIZE - 1
        hits = [
            hit
            for first in range(0, len(starts), batch)
            for hit in pb.rayTestBatch(
                starts[first : first + batch],
                ends[first : first + batch],
                collisionFilterMask=mask,
                physicsClientId=self.client,
            )
        ]
        fractions = np.fromiter(map(itemgetter(2), hits), dtype=float, count=len(hits))
        hit = np.fromiter(map(itemgetter(0), hits), dtype=np.int64, count=len(hits)) >= 0
        return np.where(hit, fractions, np.nan)
