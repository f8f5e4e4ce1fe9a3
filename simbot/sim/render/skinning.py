"""A skinned mesh's vertices at the pose a frame's joint positions give (the `body_skin_*` joints
the actors system sets: simbot.description.actor_legs), for the OpenGL renderer (each frame's
vertex buffers) and the bounding boxes (the posed vertices), so every camera output sees one pose.

Linear blend skinning on the CPU (`skeleton_poses.skin`), once per scene pose, the skin's parts
sharing its matrices: about 2 ms for the worker's 4.5k vertices on one core, the robot's six
cameras' frame set 1.085× as long with the warehouse's three people animated as rigid
(benchmarks/bench_actors.py, docs/speed.md).
A frame without the joints (a body not yet posed) shows the bind pose.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.actor_legs import ANIMATION, CLIP_TIME
from simbot.description.skeleton_poses import Rig, skin
from simbot.transform import Matrix, matmul

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Skinned:
    """One skinned part's bind vertices (skin space) and influences, and how its visual places them."""

    rig: Rig
    positions: F64
    normals: F64
    joints: npt.NDArray[np.int64]
    weights: F64
    scale: F64
    """The visual's mesh scale, per axis."""
    origin: Matrix
    """The visual's pose in its link."""

    def posed(self, joints: Mapping[str, float]) -> tuple[F64, F64]:
        """Positions and unit normals in the link frame at the pose `joints` give (N×3 each)."""
        positions, normals = self.positions, self.normals
        if CLIP_TIME in joints:
            matrices = self.rig.skinning(int(round(joints.get(ANIMATION, 0.0))), joints[CLIP_TIME])
            positions = skin(positions, self.joints, self.weights, matrices)
            normals = skin(normals, self.joints, self.weights, matrices, translate=False)
        rotation = self.origin[:3, :3]
        placed = matmul(positions * self.scale, rotation.T) + self.origin[:3, 3]
        turned = matmul(normals / self.scale, rotation.T)
        length = np.sqrt((turned * turned).sum(axis=1, keepdims=True))
        return placed, turned / np.where(length == 0.0, 1.0, length)
