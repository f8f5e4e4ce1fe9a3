"""A body of the server's physics as the render workers get it: one `SceneBody` made one way for
the Rendering system, the benchmarks and the tests, so that what a worker loads (the URDF the
physics loaded) and what it draws (the visuals of the same model, `urdf_visuals`) agree."""

from __future__ import annotations

from simbot.description.urdf_visuals import urdf_visuals
from simbot.sim.physics.protocols import WorldReader
from simbot.sim.render.specs import Annotation, SceneBody


def scene_body(
    physics: WorldReader, name: str, annotations: tuple[Annotation, ...] = (), instance: int = 0
) -> SceneBody:
    """The body `name` as the physics loaded it, where it is now, with its visuals as typed data."""
    model = physics.model_of(name)
    base = physics.body_state(name)[0]
    return SceneBody(name, physics.urdf_of(name), model.static, base, annotations, instance, urdf_visuals(model))
