"""What systems may do with the world: read it (`WorldReader`) and command it (`WorldCommands`),
by model, link and joint names. A system's context holds a `WorldAccess`, both together, so that a
system depends on these calls and not on the `Physics` class (a test may hand it a stand-in)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from simbot.description.kinematics import KinematicTree
from simbot.description.model import Model
from simbot.description.poses import IDENTITY, Pose
from simbot.sim.physics.contacts import ContactPoint
from simbot.transform import Transform, Vec3

RayBatch = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], str | None]
"""One sensor's rays: N×3 starts, N×3 ends, and the model they pass through (its own robot), or None."""
Frame = tuple[str, str, Pose]
"""A frame fixed to a link: (model, link, pose in the SDF link frame), where a sensor is."""


class FrameMotions(NamedTuple):
    """Many frames' `frame_motion` as rows, in the world frame."""

    positions: npt.NDArray[np.float64]
    """N×3."""
    orientations: npt.NDArray[np.float64]
    """N×4, xyzw."""
    linear: npt.NDArray[np.float64]
    """N×3: the velocity of each frame's origin."""
    angular: npt.NDArray[np.float64]
    """N×3."""

    @staticmethod
    def joined(parts: Sequence[FrameMotions]) -> FrameMotions:
        """Several queries' rows in one (worlds stepped together)."""
        if len(parts) == 1:
            return parts[0]
        return FrameMotions(*(np.concatenate(column) for column in zip(*parts)))


class WorldReader(Protocol):
    """Reading the world (`Queries` has the details): all a post-update system may do."""

    @property
    def step_size(self) -> float: ...

    def body_names(self) -> list[str]: ...

    def model_of(self, model: str) -> Model: ...

    def urdf_of(self, model: str) -> str: ...

    def kinematics(self, model: str) -> KinematicTree: ...

    def held_joints(self, model: str) -> frozenset[str]: ...

    def moving_bodies(self) -> list[str]: ...

    def holder(self, model: str) -> str | None: ...

    def model_pose(self, model: str) -> Transform: ...

    def model_motion(self, model: str) -> tuple[Transform, Vec3, Vec3]: ...

    def frame_pose(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> Transform: ...

    def frame_motion(self, model: str, link: str, pose_in_link: Pose = IDENTITY) -> tuple[Transform, Vec3, Vec3]: ...

    def frame_motions(self, frames: Sequence[Frame]) -> FrameMotions: ...

    def joint_states(self, model: str, joints: list[str]) -> list[tuple[float, float, float]]: ...

    def body_state(self, model: str) -> tuple[Transform, dict[str, float]]: ...

    def link_contacts(self, model: str, link: str) -> list[ContactPoint]: ...

    def joint_wrench(self, model: str, joint: str) -> tuple[Vec3, Vec3, Vec3]: ...

    def blind_rays_to(self, model: str) -> None: ...

    def cast_rays(
        self, starts: npt.NDArray[np.float64], ends: npt.NDArray[np.float64], blind_to: str | None = None
    ) -> npt.NDArray[np.float64]: ...

    def cast_ray_batches(self, batches: Sequence[RayBatch]) -> list[npt.NDArray[np.float64]]: ...


class WorldCommands(Protocol):
    """Changing the world (`Commands` has the details): in pre_update, or when a system is built."""

    def set_joint_velocity(self, model: str, joint: str, velocity: float, max_effort: float) -> None: ...

    def set_joint_force(self, model: str, joint: str, force: float) -> None: ...

    def set_joint_positions(self, model: str, positions: Mapping[str, float]) -> None: ...

    def drive_base(self, model: str, forward: float, lateral: float, turn: float) -> None: ...

    def set_model_velocity(self, model: str, linear: Vec3, angular: Vec3) -> None: ...

    def set_model_pose(self, model: str, pose: Transform) -> None: ...

    def apply_wrench(self, model: str, link: str, force: Vec3, torque: Vec3) -> None: ...

    def attach(self, parent: tuple[str, str], child: tuple[str, str]) -> int: ...

    def detach(self, constraint: int) -> None: ...

    def measure_joint_wrench(self, model: str, joint: str) -> None: ...


class WorldAccess(WorldReader, WorldCommands, Protocol):
    """What a system's context holds: the world to read and to command."""
