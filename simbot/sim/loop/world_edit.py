"""A seeded reset applied in place: what the variant a seed draws changes in the running world, as
edits of it, where loading every model and system anew took seconds (`SimWorld.reset`).

`plan_edit` compares the running world's description with the variant's, model by model (by name):
- a model alike in both stays as it is;
- one whose body is the same for the physics, its looks, its pose, an actor's script or a sensor's
  parameters aside (a texture or a tint drawn, a model moved, a person's pace and phase, a
  camera's noise), is **restyled**: the physics keeps its body (its description replaced, the body
  moved where its pose changed) and the world systems hear it leave and come back, to read it
  anew. Its own systems, which read its description when built (a person's route is its script's),
  are built anew, but where only its sensors' parameters changed: those sensors take them in
  place (`Retunable`), the others stay;
- any other is replaced, its systems with it; a model in one world only is removed or added.

The robot is never replaced: a variant whose robot differs beyond its sensors' parameters, or
whose world differs beyond its lights, scene and models, or a sensor that cannot take its new
parameters in place, cannot be applied so (`NotInPlace`, saying why): the world is then loaded anew.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Protocol, runtime_checkable

from simbot.description.actor_scripts import ActorModel, Script
from simbot.description.model import Link, Model, Sensor, Visual, World
from simbot.description.poses import IDENTITY


class NotInPlace(Exception):
    """The variant cannot be applied in place; str() says why."""


@runtime_checkable
class WorldFollower(Protocol):
    """A world system that follows an edit of the world's description in place (its lights, the
    order of its models), where another is built anew with the world."""

    def world_changed(self, world: World) -> None: ...


@runtime_checkable
class Retunable(Protocol):
    """A sensor system that takes new parameters of its `<sensor>` in place."""

    def retune(self, sensor: Sensor) -> bool:
        """Whether it took them (False: nothing changed; the world is then loaded anew)."""
        ...


@dataclass(frozen=True)
class ModelEdit:
    """What becomes of one model: removed (no `new`), added (no `old`), restyled or replaced."""

    name: str
    old: Model | None
    new: Model | None
    restyled: bool = False
    retuned: bool = False
    """Restyled, and only its sensors' parameters changed: its systems stay, those sensors retuned."""

    @property
    def moved(self) -> bool:
        return self.old is not None and self.new is not None and self.old.pose != self.new.pose


@dataclass(frozen=True)
class WorldEdit:
    models: tuple[ModelEdit, ...]
    """Every model that changes, in the variant's order (removed ones first)."""
    robot: Model | None
    """The variant's robot: the running one, but for its sensors' parameters."""


WORLD_VARIES = {"lights", "scene", "models"}
"""What of a world's description an edit in place changes."""


def plan_edit(world: World, robot: Model | None, variant_world: World, variant_robot: Model | None) -> WorldEdit:
    """How the running world (`world`, `robot`) becomes the variant's in place; NotInPlace saying why not."""
    differing = [f.name for f in fields(World) if getattr(world, f.name) != getattr(variant_world, f.name)]
    if set(differing) - WORLD_VARIES:
        raise NotInPlace(f"the variant changes the world's {', '.join(sorted(set(differing) - WORLD_VARIES))}")
    if (robot is None) != (variant_robot is None) or (
        robot is not None and variant_robot is not None and frame(robot) != frame(variant_robot)
    ):
        raise NotInPlace("the variant's robot differs from the running one beyond its sensors' parameters")
    old = {model.name: model for model in world.models}
    new = {model.name: model for model in variant_world.models}
    edits = [ModelEdit(name, model, None) for name, model in old.items() if name not in new]
    for name, model in new.items():
        before = old.get(name)
        if before != model:
            kept = before is not None and type(before) is type(model) and frame(before) == frame(model)
            retuned = kept and before is not None and _tuned_apart(before) == _tuned_apart(model)
            edits.append(ModelEdit(name, before, model, restyled=kept, retuned=retuned))
    return WorldEdit(tuple(edits), variant_robot)


def frame(model: Model) -> Model:
    """The model as its body and its systems are made of it: its pose, its visuals' materials, an
    actor's script and its sensors' parameters left out (what a restyle changes in place)."""
    shaped = replace(
        model,
        pose=IDENTITY,
        links=tuple(_link_frame(link) for link in model.links),
        joints=tuple(replace(joint, sensors=_sensor_frames(joint.sensors)) for joint in model.joints),
    )
    return replace(shaped, script=Script()) if isinstance(shaped, ActorModel) else shaped


def _tuned_apart(model: Model) -> Model:
    """The model but for its sensors' parameters."""
    return replace(
        model,
        links=tuple(replace(link, sensors=_sensor_frames(link.sensors)) for link in model.links),
        joints=tuple(replace(joint, sensors=_sensor_frames(joint.sensors)) for joint in model.joints),
    )


def _link_frame(link: Link) -> Link:
    return replace(link, visuals=tuple(_looks_apart(v) for v in link.visuals), sensors=_sensor_frames(link.sensors))


def _looks_apart(visual: Visual) -> Visual:
    return replace(visual, material=None) if visual.material is not None else visual


def _sensor_frames(sensors: tuple[Sensor, ...]) -> tuple[Sensor, ...]:
    return tuple(replace(sensor, params=()) for sensor in sensors)


def retuned(old: Model, new: Model) -> list[tuple[str, str, Sensor]]:
    """The sensors of `new` whose parameters differ from `old`'s (the same sensors otherwise): (link, name, sensor)."""
    before = {(link.name, sensor.name): sensor for link, sensor in old.sensors()}
    return [
        (link.name, sensor.name, sensor)
        for link, sensor in new.sensors()
        if before.get((link.name, sensor.name)) != sensor
    ]
