"""A URDF's kinematic tree: its links and joints as typed data, read once per body.

The physics (which links merge, which joints move, which it holds fixed) and the robot state
publisher (the transforms of `tf` and `tf_static`) both walk the joints of the URDF a model is
written as; they share this one reading of it rather than each parsing the text again. Read from
the URDF text, not worked out from the `Model`, so that every origin is the number the URDF
states (`urdf_writer` rounds to 12 digits): what PyBullet and a ROS host read.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Collection
from dataclasses import dataclass

from simbot.description.poses import Pose
from simbot.description.urdf_writer import sdf_joint

Vec3 = tuple[float, float, float]

URDF_DEFAULT_AXIS: Vec3 = (1.0, 0.0, 0.0)


@dataclass(frozen=True)
class UrdfJoint:
    """A URDF joint: its links, its origin in the parent link's frame and its axis (in its own frame)."""

    name: str
    type: str
    parent: str
    child: str
    origin: Pose
    axis: Vec3

    @property
    def fixed(self) -> bool:
        return self.type == "fixed"

    def part_of(self, joints: Collection[str]) -> bool:
        """Whether this joint is one of the SDF joints `joints` or a part of one (`sdf_joint`)."""
        return sdf_joint(self.name) in joints


@dataclass(frozen=True)
class KinematicTree:
    """The links and joints of a URDF, in document order."""

    links: tuple[str, ...]
    joints: tuple[UrdfJoint, ...]

    @staticmethod
    @functools.lru_cache(maxsize=64)
    def of_urdf(urdf: str) -> KinematicTree:
        """The tree of a URDF's text (kept: a fleet's tugs share one)."""
        root = ET.fromstring(urdf)
        return KinematicTree(
            tuple(link.get("name", "") for link in root.iter("link")),
            tuple(_joint(element) for element in root.iter("joint")),
        )

    def moving(self) -> tuple[UrdfJoint, ...]:
        """The joints that are not fixed."""
        return tuple(joint for joint in self.joints if not joint.fixed)

    def fixed_hosts(self, held: Collection[str] = ()) -> dict[str, str]:
        """Each link that a fixed joint (or one of the moving joints `held` fixed) ties to its parent,
        and the link it merges into up the chain of such joints: what PyBullet's
        URDF_MERGE_FIXED_LINKS does."""
        parents = {joint.child: (joint.parent, joint.fixed or joint.name in held) for joint in self.joints}
        hosts = {}
        for link in parents:
            host = link
            while host in parents and parents[host][1]:
                host = parents[host][0]
            if host != link:
                hosts[link] = host
        return hosts


def _joint(element: ET.Element) -> UrdfJoint:
    parent, child, axis = element.find("parent"), element.find("child"), element.find("axis")
    return UrdfJoint(
        element.get("name", ""),
        element.get("type", ""),
        parent.get("link", "") if parent is not None else "",
        child.get("link", "") if child is not None else "",
        urdf_origin(element),
        _numbers(axis.get("xyz")) if axis is not None else URDF_DEFAULT_AXIS,
    )


def urdf_origin(element: ET.Element) -> Pose:
    """The pose of a URDF joint's, visual's or collision's `<origin>` (identity without one)."""
    origin = element.find("origin")
    return Pose(_numbers(origin.get("xyz")), _numbers(origin.get("rpy"))) if origin is not None else Pose()


def _numbers(text: str | None) -> Vec3:
    x, y, z = (float(v) for v in (text or "0 0 0").split())
    return x, y, z
