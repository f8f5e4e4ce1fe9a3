"""Whether the OpenGL renderer can run here (tests of `gl` skip with this reason where no EGL context
opens), and the bodies the rendering tests draw: models made here, as the render workers get them."""

from __future__ import annotations

from pathlib import Path

from simbot.description import model_to_urdf
from simbot.description.model import Box, Inertial, Link, Material, Model, Visual
from simbot.description.poses import Pose, Vec3
from simbot.description.urdf_visuals import urdf_visuals
from simbot.sim.render import Annotation, SceneBody
from simbot.transform import Transform


def _why_no_egl() -> str | None:
    try:
        import moderngl

        moderngl.create_context(standalone=True, backend="egl", require=330).release()  # type: ignore[arg-type]  # the stub types **settings as dicts
    except Exception as exc:  # noqa: BLE001 - any failure means no GL here
        return f"no OpenGL 3.3 EGL context opens on this machine ({exc})"
    return None


NO_EGL = _why_no_egl()
"""None where an EGL context opens; else the reason, for pytest.skip."""


Rgba = tuple[float, float, float, float]
INERTIA = (0.1, 0.0, 0.0, 0.1, 0.0, 0.1)


def body_of(
    name: str,
    model: Model,
    static: bool,
    base: Transform,
    annotations: tuple[Annotation, ...] = (),
    instance: int = 0,
) -> SceneBody:
    """`model` as the render workers get it: its URDF written as the server's physics writes it,
    and its visuals as typed data."""
    return SceneBody(name, model_to_urdf(model), static, base, annotations, instance, urdf_visuals(model))


def box_model(size: Vec3, rgba: Rgba, com: Vec3 = (0.0, 0.0, 0.0), texture: Path | None = None) -> Model:
    """A one-link box of 1 kg; `com` puts its centre of mass beside the visual."""
    visual = Visual("box", Box(size), material=Material(diffuse=rgba, albedo_map=texture))
    return Model("box", links=(Link("box", inertial=Inertial(1.0, Pose(com), INERTIA), visuals=(visual,)),))


def box_body(
    name: str,
    size: Vec3,
    rgba: Rgba,
    static: bool,
    base: Transform,
    annotations: tuple[Annotation, ...] = (),
    instance: int = 0,
) -> SceneBody:
    """A one-link box (`box_model`) as the render workers get it."""
    return body_of(name, box_model(size, rgba), static, base, annotations, instance)
