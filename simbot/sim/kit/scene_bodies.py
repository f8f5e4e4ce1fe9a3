"""A body of the server's physics as the render workers get it: one `SceneBody` made one way for
the Rendering system, the benchmarks and the tests, so that what a worker loads (the URDF the
physics loaded) and what it draws (the visuals of the same model, `urdf_visuals`) agree.

A seeded reset restyles models in place (simbot.sim.loop.world_edit): the same links and visuals
in other materials. Where each visual lies in its URDF link is worked out once for a model's
shape (`_placed`), and each draw takes its own materials."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

from simbot.description.model import Model
from simbot.description.urdf_visuals import UrdfVisual, urdf_visuals
from simbot.sim.loop.world_edit import frame
from simbot.sim.physics.protocols import WorldReader
from simbot.sim.render.specs import Annotation, SceneBody


def scene_body(
    physics: WorldReader, name: str, annotations: tuple[Annotation, ...] = (), instance: int = 0
) -> SceneBody:
    """The body `name` as the physics loaded it, where it is now, with its visuals as typed data."""
    model = physics.model_of(name)
    base = physics.body_state(name)[0]
    return SceneBody(name, physics.urdf_of(name), model.static, base, annotations, instance, drawn(model))


def drawn(model: Model) -> tuple[UrdfVisual, ...]:
    """`urdf_visuals(model)`, each visual in the model's own material."""
    materials = {link.name: [visual.material for visual in link.visuals] for link in model.links}
    seen: dict[str, int] = {}
    found = []
    for placed in _placed(_Shape(frame(model), model)):
        index = seen[placed.link] = seen.get(placed.link, -1) + 1
        found.append(replace(placed, visual=replace(placed.visual, material=materials[placed.link][index])))
    return tuple(found)


@dataclass(frozen=True)
class _Shape:
    """A model known by everything its visuals' placing reads (`world_edit.frame`: not its pose,
    its visuals' materials, an actor's script, its sensors' parameters)."""

    key: Model
    model: Model = field(compare=False)


@functools.lru_cache(maxsize=1024)
def _placed(shape: _Shape) -> tuple[UrdfVisual, ...]:
    return urdf_visuals(shape.model)
