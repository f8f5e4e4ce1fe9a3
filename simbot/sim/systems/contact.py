"""Contact sensor (SDF `contact`): what the sensor's collisions touch, with points, normals and forces.

As Gazebo's Contact system: at each sample with at least one contact, one message listing a
contact per pair of touching collisions, named by scoped name (`model::link::collision`, the
model by its name in the running world), each with its points (world frame), normals (unit,
pushing collision1, the sensor's, away from collision2), penetration depths and, per point, the
force on collision1 (normal force and friction, N) as `JointWrench`es; nothing while there is no
contact. Published as ros_gz_interfaces/Contacts, the type ros_gz_bridge gives Gazebo's, on
`<contact><topic>` when set (as gz-sim has it), else `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/contact`.

PyBullet merges a link's collisions into one compound shape and reports contacts per link: where
a link has several collisions a contact names the first the sensor lists (its own side) or the
link's first (the other side).

SDF parameters (under `<contact>`; `ContactParams`):

| element | default | meaning |
| --- | --- | --- |
| `<collision>` (one or more) | required | the collisions of the sensor's link that sense |
| `<topic>` | `__default_topic__` | the key, when not the default |
| `<update_rate>` (of the `<sensor>`) | the physics rate | samples per second |
"""

from __future__ import annotations

from dataclasses import dataclass

from simbot.bus import messages
from simbot.description.model import Link, Sensor
from simbot.description.naming import sensor_frame, sensor_rate
from simbot.description.sensor_params import SdfElement
from simbot.sim.kit.rates import Sampled
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.sim.physics import ContactPoint, WorldReader

DEFAULT_TOPIC = "__default_topic__"


@dataclass(frozen=True)
class ContactParams:
    """A contact sensor's SDF parameters (the table in the module docstring)."""

    collisions: tuple[str, ...]
    topic: str | None = None

    @staticmethod
    def from_sdf(sensor: Sensor, link: Link) -> ContactParams:
        element = SdfElement.of(sensor).require("contact")
        names = tuple(element.texts("collision"))
        if not names:
            raise element.error("collision", "is required: name a collision of the sensor's link")
        known = [collision.name for collision in link.collisions]
        for name in names:
            if name not in known:
                raise element.error("collision", f"{name!r} is not a collision of link {link.name!r} ({known})")
        topic = element.text("topic")
        return ContactParams(names, None if topic in (None, DEFAULT_TOPIC) else topic)


def collision_name(physics: WorldReader, model: str, link: str) -> str:
    """The scoped name of a link's (first) collision, `model::link::collision`; the link's where it has none."""
    if not model:
        return "unknown"
    collisions = physics.model_of(model).link(link).collisions
    return "::".join((model, link, collisions[0].name) if collisions else (model, link))


class Contact(Sampled):
    """ros_gz_interfaces/Contacts at the sensor's rate while its link touches something."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        self.params = ContactParams.from_sdf(sensor, link)
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self._physics = ctx.physics
        self._where = (model, link.name)
        self._name = f"{model}::{link.name}::{self.params.collisions[0]}"
        self._frame = sensor_frame(sensor)
        topic = (self.params.topic or "").strip().strip("/") or ctx.sensor_topic("contact")
        self._pub = ctx.bus.publisher(topic, messages.Contacts)

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        pairs = self._pairs(self._physics.link_contacts(*self._where))
        if pairs:
            self._pub.put(messages.contacts(info.sim_time_ns, self._frame, pairs))
            self.published(info.sim_time_ns)

    def _pairs(self, points: list[ContactPoint]) -> list[messages.ContactPair]:
        """The points grouped by the link they touch, in the order PyBullet reports them."""
        by_other: dict[tuple[str, str], list[ContactPoint]] = {}
        for point in points:
            by_other.setdefault(point.other, []).append(point)
        return [
            messages.ContactPair(
                self._name,
                collision_name(self._physics, *other),
                [p.position for p in group],
                [p.normal for p in group],
                [p.depth for p in group],
                [p.force for p in group],
            )
            for other, group in by_other.items()
        ]
