"""ros_gz_interfaces, Gazebo's own messages: the altimeter's reading and the contacts of a contact sensor."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from simbot.bus.messages.geometry import vector3, wrench
from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import Altimeter, Contact, Contacts, Entity, Header, JointWrench, String, UInt32
from simbot.bus.messages.values import Floats, float_array, three


def altimeter(ns: int, frame: str, position: float, velocity: float, reference: float) -> Any:
    """ros_gz_interfaces/Altimeter: height over the reference and vertical velocity (m, m/s), the reference (m)."""
    return Altimeter(
        header=header(ns, frame),
        vertical_position=float(position),
        vertical_velocity=float(velocity),
        vertical_reference=float(reference),
    )


@dataclass(frozen=True)
class ContactPair:
    """Where two collisions touch: the points (world), normals (unit, pushing collision1 away from
    collision2), penetration depths, and the force on collision1 at each point (N)."""

    collision1: str
    collision2: str
    positions: Sequence[Floats]
    normals: Sequence[Floats]
    depths: Sequence[float]
    forces: Sequence[Floats]


def contacts(ns: int, frame: str, pairs: Iterable[ContactPair]) -> Any:
    """ros_gz_interfaces/Contacts as ros_gz_bridge writes Gazebo's: a Contact per pair of collisions
    (scoped names `model::link::collision`), a JointWrench per point (body 2's wrench the opposite)."""
    stamp = header(ns, frame)
    entity_type = Entity.COLLISION
    return Contacts(
        header=stamp,
        contacts=[
            Contact(
                collision1=Entity(id=0, name=pair.collision1, type=entity_type),
                collision2=Entity(id=0, name=pair.collision2, type=entity_type),
                positions=[vector3(*three(p, "contact position")) for p in pair.positions],
                normals=[vector3(*three(n, "contact normal")) for n in pair.normals],
                depths=float_array(pair.depths, "depths"),
                wrenches=[_joint_wrench(stamp, pair, force) for force in pair.forces],
            )
            for pair in pairs
        ],
    )


def _joint_wrench(stamp: Header, pair: ContactPair, force: Floats) -> Any:
    on_1 = np.asarray(three(force, "contact force"))
    none = (0.0, 0.0, 0.0)
    return JointWrench(
        header=stamp,
        body_1_name=String(data=pair.collision1),
        body_1_id=UInt32(data=0),
        body_2_name=String(data=pair.collision2),
        body_2_id=UInt32(data=0),
        body_1_wrench=wrench(on_1, none),
        body_2_wrench=wrench(-on_1, none),
    )
