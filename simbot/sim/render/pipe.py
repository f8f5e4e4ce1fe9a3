"""The messages on the pipe between the render pool and a worker: small frozen dataclasses, each
side dispatching on their type. The pixels never cross it: they lie in shared memory.

Pool → worker: `RenderRequest`, the scene changes (`EditScene`, `AddCamera`, `UpdateCamera`), `Stop`.
Worker → pool: once `Ready` or `StartError`; then per request `FrameDone` or `RenderFailed`, per
edit `SceneEdited` (with what failed of it), and `SceneFailed` for another change that failed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from simbot.sim.render.publishing import Publication
from simbot.sim.render.specs import BodyState, CameraSpec, Light, SceneBody
from simbot.transform import Transform


@dataclass(frozen=True)
class RenderRequest:
    camera: int
    stamp_ns: int
    pose: Transform
    """The camera's world pose, looking along its +x with z up."""
    states: Mapping[str, BodyState]
    """The moving bodies, where they are at the stamp."""
    publish: frozenset[str] = frozenset()
    """The keys of the camera's publication that go out with the frame: those the server found
    subscribed when it asked for it (`publishing.FramePublisher.publish`)."""


@dataclass(frozen=True)
class EditScene:
    """One change of the world, applied whole before any later request, with one rebuild of what
    the renderer batches: the bodies `removed`, then those `added` (a name in both is the body
    replaced: one whose description changed, kept in the worker's physics where its URDF did not),
    the world's new lighting, and the order a world loaded afresh would hold its bodies in."""

    removed: tuple[str, ...] = ()
    added: tuple[SceneBody, ...] = ()
    light: Light | None = None
    """None: the lighting stays."""
    order: tuple[str, ...] = ()
    """Every body of the scene after the edit, in the order a world loaded afresh holds them: the
    renderer batches them in it, so that an edited world draws as a fresh one."""

    def __str__(self) -> str:
        names = [*(f"remove {n!r}" for n in self.removed), *(f"add {b.name!r}" for b in self.added)]
        return "edit (" + ", ".join(names + (["light"] if self.light is not None else [])) + ")"


@dataclass(frozen=True)
class AddCamera:
    index: int
    spec: CameraSpec
    shm_name: str
    """The camera's shared memory block, created by the pool."""
    publication: Publication | None = None
    """What the worker publishes of its frames; None: the server publishes them."""

    def __str__(self) -> str:
        return f"add_camera {self.index!r}"


@dataclass(frozen=True)
class UpdateCamera:
    """A camera's spec changed where its buffers allow (its noise, its seed): its outputs are
    finished anew from it, its noise started again from its seed."""

    index: int
    spec: CameraSpec

    def __str__(self) -> str:
        return f"update_camera {self.index!r}"


SceneChange = EditScene | AddCamera | UpdateCamera


@dataclass(frozen=True)
class Stop:
    """Finish the current frame, release everything, exit."""


@dataclass(frozen=True)
class Ready:
    renderer: str
    """"gl" or "tiny"."""
    fallback_reason: str | None
    """Why `auto` fell back to TinyRenderer; None when it did not."""
    device: str


@dataclass(frozen=True)
class StartError:
    reason: str


@dataclass(frozen=True)
class FrameDone:
    camera: int
    stamp_ns: int
    render_s: float


@dataclass(frozen=True)
class RenderFailed:
    camera: int
    stamp_ns: int
    reason: str


@dataclass(frozen=True)
class SceneEdited:
    """An `EditScene` applied: what the pool waits for before it counts the edit done."""

    failures: tuple[str, ...] = ()
    """What of it failed (`add_body 'name': why`); the rest was applied."""


@dataclass(frozen=True)
class SceneFailed:
    reason: str
    """Which change failed (`add_body 'name'`), and why."""
