"""A model as loaded into PyBullet: its body id and the indices of its links and joints, by name,
and bodies' bases read as rows (`Bases`). Nothing outside the physics package sees them: systems
name a model, a link or a joint."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from simbot.description.kinematics import KinematicTree
from simbot.description.model import Model
from simbot.sim.bullet import pb
from simbot.transform import Transform


@dataclass
class Body:
    """A model as loaded: its PyBullet id and its names."""

    name: str
    model: Model
    id: int
    links: dict[str, int]
    joints: dict[str, int]
    com_to_root: Transform
    """The root link's URDF frame seen from PyBullet's base (centre of mass) frame."""
    com_to_frame: Transform
    """The SDF model frame seen from PyBullet's base (centre of mass) frame."""
    urdf: str
    """The model's URDF (what `robot_description` publishes and the renderer draws). PyBullet may
    load it leaner (`Physics.fixed_castors`, `Physics.merge_fixed_links`): look links up here."""
    tree: KinematicTree
    """The links and joints of `urdf`."""
    castors: frozenset[str] = frozenset()
    """The model's ball castors (`ball_castors`)."""
    hosts: dict[str, str] = field(default_factory=dict)
    """Each link's host: the link PyBullet simulates it as part of (itself, or the link a chain of
    fixed joints ties it to, when fixed links are merged). `links` maps a link to its host's index."""
    drawn: tuple[str, ...] = ()
    """The joints that move in `urdf`: what the renderer poses."""
    held: frozenset[str] = frozenset()
    """Joints that move in `urdf` but that PyBullet holds fixed (ball castors): they read 0."""

    @property
    def indices(self) -> list[int]:
        """PyBullet's link indices of the body, each once (merged links share their host's), in order."""
        return sorted(set(self.links.values()))

    def link_index(self, link: str) -> int:
        try:
            return self.links[link]
        except KeyError:
            raise KeyError(f"model {self.name!r} has no link {link!r}") from None

    def joint_index(self, joint: str) -> int:
        try:
            return self.joints[joint]
        except KeyError:
            raise KeyError(f"model {self.name!r} has no movable joint {joint!r}") from None


class Bases(NamedTuple):
    """Bodies' bases as PyBullet holds them, a row each: each root link's centre of mass and its
    velocity, in the world frame (what `Stepper.bases` answers)."""

    positions: npt.NDArray[np.float64]
    """N×3."""
    orientations: npt.NDArray[np.float64]
    """N×4, xyzw."""
    linear: npt.NDArray[np.float64]
    """N×3."""
    angular: npt.NDArray[np.float64]
    """N×3."""

    @staticmethod
    def read(client: int, ids: Sequence[int]) -> Bases:
        """The bases of PyBullet bodies `ids`, one query each."""
        rows = []
        for body in ids:
            position, orientation = pb.getBasePositionAndOrientation(body, physicsClientId=client)
            rows.append((*position, *orientation, *sum(pb.getBaseVelocity(body, physicsClientId=client), ())))
        table = np.array(rows, dtype=np.float64).reshape(-1, 13)
        return Bases(table[:, :3], table[:, 3:7], table[:, 7:10], table[:, 10:])


def read_joint_states(client: int, body: int, joints: Sequence[int]) -> list[tuple[float, float, float]]:
    """(position, velocity, motor effort) of each joint of a PyBullet body, as PyBullet holds them."""
    states = pb.getJointStates(body, list(joints), physicsClientId=client) if joints else []
    return [(float(s[0]), float(s[1]), float(s[3])) for s in states]


def write_joint_positions(
    client: int, body: int, joints: Sequence[int], values: Sequence[float], velocities: Sequence[float] = ()
) -> None:
    """Joints of a PyBullet body put at `values`, turning at `velocities` (none given: at rest)."""
    speeds = [[speed] for speed in velocities] or [[0.0]] * len(values)
    pb.resetJointStatesMultiDof(body, list(joints), [[value] for value in values], speeds, physicsClientId=client)
