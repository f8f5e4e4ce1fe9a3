"""The messages on the pipe between the render pool and a worker: small frozen dataclasses, each
side dispatching on their type. The pixels never cross it: they lie in shared memory.

Pool → worker: `RenderRequest`, the scene changes (`AddBody`, `RemoveBody`, `AddCamera`), `Stop`.
Worker → pool: once `Ready` or `StartError`; then per request `FrameDone` or `RenderFailed`, and
`SceneFailed` for a change that failed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from simbot.sim.render.publishing import Publication
from simbot.sim.render.specs import BodyState, CameraSpec, SceneBody
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
class AddBody:
    body: SceneBody

    def __str__(self) -> str:
        return f"add_body {self.body.name!r}"


@dataclass(frozen=True)
class RemoveBody:
    name: str

    def __str__(self) -> str:
        return f"remove_body {self.name!r}"


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


SceneChange = AddBody | RemoveBody | AddCamera


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
class SceneFailed:
    reason: str
    """Which change failed (`add_body 'name'`), and why."""
