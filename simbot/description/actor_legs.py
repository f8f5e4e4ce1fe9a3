"""An animated actor's collision proxy: a capsule per thigh and shin (and one for the torso), on
joints that the actors system sets each step from the skeleton's pose, so that a lidar sees two
legs that swing.

The legs are found by name: a joint named like a thigh (`thigh`, `upleg`, `upperleg`, any case)
on the left or the right (`left`/`l_`/`_l`, `right`/`r_`/`_r`), its first child the shin and the
shin's the foot. The proxy's links hang from the actor's `body`:

- `body_pelvis` on a prismatic joint along z (the pelvis's rise and dip in the clip), holding
- `body_thigh_<side>` on a continuous joint about y at the hip, a capsule from the hip to the knee,
  holding `body_shin_<side>` on one at the knee, a capsule from the knee to the ankle;
- the torso: a capsule on `body` from the hips to the top of the head, TORSO_RADIUS.

Each joint's angle is the pitch of its bone (about the skin's y axis, the walk's plane) less its
rest pitch; the legs' radius is the shin's vertices' distance from its axis. The gait itself rides
on two more prismatic joints (no shape): `body_skin_time`, seconds into the clip, and
`body_skin_animation`, the `<animation>`'s index: every camera poses the skin from them as the
frame's joint positions say, and the bounding boxes too.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.model import Axis, Capsule, Collision, Joint, Link
from simbot.description.poses import Pose
from simbot.description.skeleton_poses import Rig, global_pose
from simbot.description.skeletons import Skeleton

F64 = npt.NDArray[np.float64]
TORSO_RADIUS = 0.2
"""Metres: a standing adult's chest, front to back, with the arms by the sides."""
LEG_RADIUS = 0.07
"""Metres, where the skin has no vertex on a shin to measure."""
CLIP_TIME = "body_skin_time"
ANIMATION = "body_skin_animation"
PELVIS = "body_pelvis_z"
GAIT_SAMPLES = 200
"""Leg angles tabled per clip: a 1.1 s walk every 5.5 ms, finer than a camera frame."""
_THIGH = re.compile(r"thigh|up_?leg|upper_?leg", re.IGNORECASE)
_LEFT = re.compile(r"left|^l_|_l$|^l(?=[A-Z])", re.IGNORECASE)
_RIGHT = re.compile(r"right|^r_|_r$|^r(?=[A-Z])", re.IGNORECASE)
_FREE = Axis((0.0, 0.0, 1.0), lower=-1e6, upper=1e6)
_LEG_LINK = re.compile(r"body_(thigh|shin)_(left|right)")


def is_leg_link(name: str) -> bool:
    """Whether a link is a leg's capsule of the proxy (`ActorRig.links`): collision only, never drawn."""
    return _LEG_LINK.fullmatch(name) is not None


@dataclass(frozen=True)
class Leg:
    side: str
    thigh: int
    shin: int
    foot: int


def legs_of(skeleton: Skeleton) -> tuple[Leg, ...]:
    """The skeleton's two legs, left first; none where they are not both found."""
    children = {parent: joint for joint, parent in reversed(list(enumerate(skeleton.parents)))}
    found = {}
    for joint, name in enumerate(skeleton.names):
        side = "left" if _LEFT.search(name) else "right" if _RIGHT.search(name) else None
        shin = children.get(joint)
        foot = children.get(shin) if shin is not None else None
        if side and side not in found and _THIGH.search(name) and shin is not None and foot is not None:
            found[side] = Leg(side, joint, shin, foot)
    return (found["left"], found["right"]) if len(found) == 2 else ()


def _pitch(v: F64) -> float:
    """The turn about y that takes straight down (−z) to v's direction in the x–z plane."""
    return math.atan2(-float(v[0]), -float(v[2]))


@dataclass(frozen=True, eq=False)
class ActorRig:
    """A skin's rig with its legs found, at the skin's scale: the proxy's links and their joint positions."""

    rig: Rig
    legs: tuple[Leg, ...]
    scale: float
    rest: F64
    """J×4×4 rest pose in skin space."""

    @staticmethod
    def of(rig: Rig, scale: float) -> ActorRig:
        return ActorRig(rig, legs_of(rig.skeleton), scale, global_pose(rig.skeleton, rig.skeleton.rest))

    def _at(self, pose: F64, joint: int) -> F64:
        return pose[joint, :3, 3] * self.scale

    def links(self, parent: str) -> tuple[tuple[Link, ...], tuple[Joint, ...]]:
        """The legs' links and joints, hanging from `parent` (see the module docstring)."""
        radius = self.leg_radius()
        links = [Link("body_pelvis"), Link("body_skin_clip"), Link("body_skin_choice")]
        joints = [
            Joint(PELVIS, "prismatic", parent, "body_pelvis", axis=_FREE),
            Joint(CLIP_TIME, "prismatic", parent, "body_skin_clip", axis=_FREE),
            Joint(ANIMATION, "prismatic", parent, "body_skin_choice", axis=_FREE),
        ]
        for leg in self.legs:
            hip, knee, ankle = (self._at(self.rest, j) for j in (leg.thigh, leg.shin, leg.foot))
            for part, top, bottom, above in (
                ("thigh", hip, knee, "body_pelvis"),
                ("shin", knee, ankle, f"body_thigh_{leg.side}"),
            ):
                name = f"body_{part}_{leg.side}"
                where = Pose((float(top[0]), float(top[1]), float(top[2])))
                bone = bottom - top
                length = float(np.sqrt((bone * bone).sum()))
                shape = Capsule(radius, max(length, 1e-3))
                half = (float(bone[0] / 2), float(bone[1] / 2), float(bone[2] / 2))
                centre = Pose(half, (0.0, math.atan2(float(bone[0]), float(bone[2])), 0.0))
                links.append(Link(name, where, collisions=(Collision(f"{part}_{leg.side}", shape, centre),)))
                joint = f"body_{'hip' if part == 'thigh' else 'knee'}_{leg.side}"
                joints.append(Joint(joint, "continuous", above, name, where, Axis((0.0, 1.0, 0.0))))
        return tuple(links), tuple(joints)

    def torso(self) -> Collision | None:
        """A capsule from the hips to the top of the skin; None where that is shorter than its width."""
        hips = max(float(self._at(self.rest, leg.thigh)[2]) for leg in self.legs)
        top = max(float(p.positions[:, 2].max()) for p in self.rig.skeleton.parts) * self.scale
        length = top - hips - 2 * TORSO_RADIUS
        if length <= 0.0:
            return None
        return Collision("torso", Capsule(TORSO_RADIUS, length), Pose((0.0, 0.0, (top + hips) / 2)))

    def lowest(self) -> float:
        """The skin's lowest z in the actor frame."""
        return min(float(p.positions[:, 2].min()) for p in self.rig.skeleton.parts) * self.scale

    def leg_radius(self) -> float:
        """The median distance of the shins' vertices from their axes."""
        distances = []
        for leg in self.legs:
            knee, ankle = self.rest[leg.shin, :3, 3], self.rest[leg.foot, :3, 3]
            axis = (ankle - knee) / max(float(np.sqrt(((ankle - knee) ** 2).sum())), 1e-9)
            for part in self.rig.skeleton.parts:
                mine = part.positions[(part.joints[:, 0] == leg.shin) & (part.weights[:, 0] > 0.99)]
                offsets = mine - knee
                along = (offsets * axis).sum(axis=1)
                across = offsets - along[:, None] * axis
                distances += np.sqrt((across * across).sum(axis=1)).tolist()
        return float(np.median(distances)) * self.scale if distances else LEG_RADIUS

    def positions(self, animation: int, time: float) -> dict[str, float]:
        """The proxy's joint positions with the skin at `time` seconds into clip `animation`."""
        pose = self.rig.pose(animation, time)
        out = {CLIP_TIME: time, ANIMATION: float(animation)}
        hips = []
        for leg in self.legs:
            hip, knee, ankle = (self._at(pose, j) for j in (leg.thigh, leg.shin, leg.foot))
            rest_hip, rest_knee, rest_ankle = (self._at(self.rest, j) for j in (leg.thigh, leg.shin, leg.foot))
            thigh = _pitch(knee - hip) - _pitch(rest_knee - rest_hip)
            out[f"body_hip_{leg.side}"] = thigh
            out[f"body_knee_{leg.side}"] = _pitch(ankle - knee) - _pitch(rest_ankle - rest_knee) - thigh
            hips.append(float(hip[2] - rest_hip[2]))
        out[PELVIS] = sum(hips) / len(hips) if hips else 0.0
        return out
