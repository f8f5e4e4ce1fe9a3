"""Contact points as systems see them: in the world frame, the other side named, the forces on the asked link."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from simbot.sim.physics.bullet_transforms import vec3
from simbot.transform import Vec3, matmul


@dataclass(frozen=True)
class ContactPoint:
    """A point where a link touches another body (`Physics.link_contacts`), in the world frame."""

    other: tuple[str, str]
    """(model, link) touched."""
    position: Vec3
    normal: Vec3
    """Unit, from the other body towards the link."""
    depth: float
    """Penetration, positive where the two overlap."""
    force: Vec3
    """On the link: normal force and friction."""


def contact_point(point: tuple[Any, ...], other: tuple[str, str]) -> ContactPoint:
    """One of PyBullet's contact points, its other body (model, link) named `other`. PyBullet turns
    the normal round when it swaps the pair to put the asked body first, but not the friction
    directions, which it builds as a right-handed (normal, dir1, dir2): where they are left-handed
    with the reported normal, the pair was swapped and the friction forces on the asked body are the
    opposite of the reported ones."""
    a, b, normal, dir_1, dir_2 = (np.asarray(point[i], dtype=float) for i in (5, 6, 7, 11, 13))
    swapped = float(matmul(dir_2, np.cross(normal, dir_1))) < 0
    friction = (point[10] * dir_1 + point[12] * dir_2) * (-1.0 if swapped else 1.0)
    return ContactPoint(other, vec3((a + b) / 2), vec3(normal), -float(point[8]), vec3(point[9] * normal + friction))
