"""What a camera-type sensor and the rendering system agree on, so that neither imports the other.

A sensor that renders implements `RenderedSensor`; the world's rendering system
(simbot/sim/systems/camera_rendering.py) finds such sensors among the systems of each model that enters
the world, schedules them, and tells them how rendering goes through their `status`. A system
that says what cameras see of a model's visuals (Label, Thermal) implements `Annotating`: the
rendering system hands its annotation to the render workers with the model's bodies; `covered`
says which visuals it covers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from simbot.description.poses import Pose
from simbot.sim.loop.system import SystemContext, UpdateInfo
from simbot.sim.render.publishing import Publication
from simbot.sim.render.specs import Annotation, CameraSpec, Frame


@dataclass
class RenderStatus:
    """How a camera's rendering goes: which renderer draws it, or why it stopped. The rendering
    system writes it; the camera reports it in world state."""

    renderer: str | None = None
    """"gl" or "tiny" once the render pool runs."""
    failure: str | None = None
    """Why the cameras stopped (a worker died, the pool did not start)."""


@runtime_checkable
class RenderedSensor(Protocol):
    """What a camera-type sensor gives the rendering system."""

    spec: CameraSpec
    where: tuple[str, str, Pose]
    """(model, link, pose in the link): where the camera is, looking along its +x with z up."""
    skipped: int
    status: RenderStatus
    publication: Publication | None
    """What the render worker publishes of its frames (`publishing.py`); None: `publish` does."""

    def due(self, info: UpdateInfo) -> bool: ...

    def resume(self, info: UpdateInfo, since_ns: int = 0) -> None:
        """Its rate brought up to this step, as if `due` had been asked at every step after
        `since_ns`, the sim time it came into the world (the rendering system passes over cameras no
        one watches)."""
        ...

    @property
    def next_due_ns(self) -> int:
        """Sim time before which `due` says False."""
        ...

    def wanted(self) -> bool:
        """Someone subscribes to an output that needs rendering."""
        ...

    def audience(self) -> frozenset[str]:
        """The keys of its `publication` someone subscribes to now: what its worker puts of the
        frame asked for now (the server's view, never the worker's session's)."""
        ...

    def publish_info(self, stamp_ns: int) -> None:
        """camera_info alone, for a tick with no frame to render."""
        ...

    def publish(self, frame: Frame) -> None:
        """A frame done: its messages and its camera_info under the frame's stamp (where its worker
        did not publish them), and what else the sensor does with a frame."""
        ...


@runtime_checkable
class Annotating(Protocol):
    """A system that labels a model's visuals or gives them a temperature."""

    annotation: Annotation


def covered(ctx: SystemContext, system: str) -> tuple[str | None, str | None]:
    """What an `Annotating` system covers: (link, visual) of a plugin in a `<visual>`; (None, None)
    for one on a model: all its visuals."""
    ctx.require_model(system)
    if ctx.visual is None or ctx.link is None:
        return None, None
    return ctx.link.name, ctx.visual.name
