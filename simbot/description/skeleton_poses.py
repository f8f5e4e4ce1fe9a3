"""A skin's pose at an instant: shared by the server (the legs' collision proxies) and the render
workers (the skinned mesh), so both see one pose.

- The clip's time: with `<interpolate_x>` (and a clip whose root moves along x) the distance walked
  over the clip's stride, as gz-sim plays it (a cycle per `x_displacement` metres); else the sim
  time, looping.
- The root's own walk along x is taken out (the actor's trajectory moves it), so the skin stays
  on its frame.
- An `<animation>`'s `<scale>` multiplies a COLLADA clip's translations (every joint's offset from
  its parent, the root's walk with them), as Gazebo scales an animation's skeleton (gz-common's
  `Skeleton::Scale`): a clip made for a taller or shorter figure. A BVH clip's `<scale>` multiplies
  the BVH's own offsets and positions only, as gz-common's BVHLoader does (`bvh_clips.py`).
- Keys are interpolated per joint: translations linearly, rotations by normalised linear
  interpolation of their quaternions (the keys of a walk are dense; it stays within a degree of
  slerp).
- Skinning matrices: each joint's pose in skin space times its inverse bind matrix; a vertex is
  the weighted sum of its joints' matrices applied to it (linear blend skinning).

Sums are written term by term (no BLAS), so a pose is the same bits on every CPU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from simbot.description.bvh_clips import read_bvh_clip
from simbot.description.skeletons import Clip, Skeleton, SkeletonError, read_clip, read_skeleton
from simbot.transform import matrices_to_quaternions, quaternions_to_matrices

F64 = npt.NDArray[np.float64]


class ClipFile(NamedTuple):
    """An `<animation>` as the skin's rig plays it."""

    path: Path
    interpolate_x: bool = False
    scale: float = 1.0


@dataclass(frozen=True, eq=False)
class Rig:
    """A skin's skeleton and its animations' clips, in the order of the actor's `<animation>`s."""

    skeleton: Skeleton
    clips: tuple[Clip, ...]
    interpolate_x: tuple[bool, ...]

    def clip_time(self, animation: int, sim_time: float, distance: float) -> float:
        """Seconds into clip `animation` at `sim_time`, `distance` metres walked (see the module docstring)."""
        clip = self.clips[animation]
        if clip.duration <= 0.0:
            return 0.0
        stride = abs(clip.x_displacement)
        if self.interpolate_x[animation] and stride > 1e-9:
            return math.fmod(distance, stride) / stride * clip.duration
        return math.fmod(sim_time, clip.duration)

    def pose(self, animation: int, time: float) -> F64:
        """Each joint's J×4×4 transform in skin space at `time` seconds into clip `animation`."""
        return global_pose(self.skeleton, local_pose(self.clips[animation], time))

    @lru_cache(maxsize=4)  # noqa: B019 - rigs live as long as load_rig's cache: a skin's parts share a pose
    def skinning(self, animation: int, time: float) -> F64:
        """J×4×4 skinning matrices: the pose times the inverse bind matrices (worked out once for
        all of a skin's parts)."""
        return products(self.pose(animation, time), self.skeleton.inverse_bind)


@cache
def load_rig(skin: Path, animations: tuple[ClipFile, ...]) -> Rig:
    """The skin's skeleton and each animation's clip, scaled; SkeletonError saying which file and why
    where one cannot be used."""
    try:
        skeleton = read_skeleton(skin)
    except SkeletonError as exc:
        raise SkeletonError(f"skin {skin}: {exc}") from None
    clips = []
    for animation in animations:
        try:
            clips.append(read_animation(animation, skeleton))
        except SkeletonError as exc:
            raise SkeletonError(f"animation {animation.path}: {exc}") from None
    return Rig(skeleton, tuple(clips), tuple(a.interpolate_x for a in animations))


def read_animation(animation: ClipFile, skeleton: Skeleton) -> Clip:
    """The animation's clip of `skeleton`, scaled: a `.bvh` file as gz-common's BVHLoader reads it
    (the BVH's own translations scaled), any other as COLLADA (the clip's translations scaled)."""
    if animation.path.suffix.lower() == ".bvh":
        return read_bvh_clip(animation.path, skeleton, animation.scale)
    return read_clip(animation.path, skeleton).scaled(animation.scale)


def local_pose(clip: Clip, time: float) -> F64:
    """J×4×4 local transforms at `time` (clamped to the clip), the root's drift along x taken out."""
    times = clip.times
    time = min(max(time, 0.0), clip.duration)
    k = min(int(np.searchsorted(times, time, side="right")) - 1, len(times) - 2) if len(times) > 1 else 0
    if len(times) == 1:
        out = clip.locals[0].copy()
    else:
        fraction = (time - times[k]) / (times[k + 1] - times[k])
        out = _blend(clip.locals[k], clip.locals[k + 1], fraction)
    if clip.duration > 0.0:
        out[0, 0, 3] -= clip.x_displacement * time / clip.duration
    return out


def _blend(a: F64, b: F64, t: float) -> F64:
    """Per joint: translation lerp, rotation nlerp (the shorter way)."""
    qa, qb = _quaternions(a[:, :3, :3]), _quaternions(b[:, :3, :3])
    sign = np.where((qa * qb).sum(axis=1) < 0.0, -1.0, 1.0)[:, None]
    q = (1.0 - t) * qa + t * sign * qb
    q /= np.sqrt((q * q).sum(axis=1))[:, None]
    out = np.tile(np.eye(4), (len(a), 1, 1))
    out[:, :3, :3] = quaternions_to_matrices(q)
    out[:, :3, 3] = (1.0 - t) * a[:, :3, 3] + t * b[:, :3, 3]
    return out


def _quaternions(m: F64) -> F64:
    """N×3×3 rotations as N×4 (x, y, z, w); the rotation part of a scaled matrix's columns normalised."""
    return matrices_to_quaternions(m / np.sqrt((m * m).sum(axis=1))[:, None, :])


def products(a: F64, b: F64) -> F64:
    """a[i] · b[i] for stacks of 4×4 matrices, summed term by term."""
    terms = a[:, :, :, None] * b[:, None, :, :]
    return terms[:, :, 0] + terms[:, :, 1] + terms[:, :, 2] + terms[:, :, 3]


def global_pose(skeleton: Skeleton, local: F64) -> F64:
    """Each joint's transform in skin space: its parents' composed with its own (parents come first)."""
    out = local.copy()
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            out[joint] = products(out[parent : parent + 1], local[joint : joint + 1])[0]
    return out


def skin(points: F64, joints: npt.NDArray[np.int64], weights: F64, matrices: F64, translate: bool = True) -> F64:
    """Linear blend skinning of N×3 points (or, `translate` false, directions) by their joints' matrices."""
    out = np.zeros_like(points)
    for k in range(joints.shape[1]):
        if not weights[:, k].any():
            continue  # an influence no vertex uses (a rigid part's second to fourth)
        m = matrices[joints[:, k]]
        moved = m[:, :, 0] * points[:, 0:1] + m[:, :, 1] * points[:, 1:2] + m[:, :, 2] * points[:, 2:3]
        if translate:
            moved = moved + m[:, :, 3]
        out += weights[:, k : k + 1] * moved[:, :3]
    return out
