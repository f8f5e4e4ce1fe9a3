"""A render worker process: its own copy of the scene, one renderer, requests in order.

The worker loads the scene (`BulletScene`), opens the renderer it was asked for (`gl`, `tiny`, or
`auto`: gl when an EGL context opens, else tiny with the reason), reports ready, then takes the
pool's messages (typed: `pipe.py`) in order until told to stop or the server is gone: render
requests, and the changes of a world that runs (an edit: bodies out and in, the lighting; a camera
added, or its noise changed), each before any request sent after it; an edit is answered when
applied (`SceneEdited`). Each frame is drawn straight into the camera's shared memory
and finished there (each output kind's finishing step, `kinds.py`); only a small message goes
back. A camera the server gave a publication has its frame published from here
(`publishing.py`) before the frame is reported done. A change that fails is reported (with the
edit's answer, or `SceneFailed`) and the worker goes on.
"""

from __future__ import annotations

import os
import signal
import sys
import time
import traceback
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Protocol

import numpy as np

from simbot.sim.render.kinds import Array, Finish, Raw
from simbot.sim.render.pipe import (
    AddCamera,
    EditScene,
    FrameDone,
    Ready,
    RenderFailed,
    RenderRequest,
    SceneChange,
    SceneEdited,
    SceneFailed,
    StartError,
    Stop,
    UpdateCamera,
)
from simbot.sim.render.publishing import Bus, FramePublisher, Publication
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.specs import BodyState, CameraSpec, Light, SceneBody
from simbot.sim.render.starter import take_environment
from simbot.sim.render.wide_angle import views
from simbot.transform import Transform

RENDERERS = ("auto", "gl", "tiny")


class Renderer(Protocol):
    name: str
    device: str

    def render(self, camera: int, pose: Transform, drawn: Mapping[Raw, Array]) -> None:
        """Draw camera `camera` at `pose` into the raw buffers it draws (`CameraSpec.drawn`)."""
        ...

    def add_camera(self, index: int, spec: CameraSpec) -> None: ...

    def edit(self, removed: Collection[str], added: Collection[str], light: Light | None, order: Sequence[str]) -> None:
        """After the scene has dropped `removed` and loaded `added` (`pipe.EditScene`)."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class WorkerPlan:
    """What a worker is asked to do."""

    bodies: tuple[SceneBody, ...]
    jobs: dict[int, tuple[CameraSpec, str, Publication | None]]
    """Camera index → (spec, shared memory name, what the worker publishes of it)."""
    renderer: str
    light: Light
    gl_threads: int | None
    """LP_NUM_THREADS for Mesa's llvmpipe (None: Mesa's default, one per core)."""
    bus: Bus | None = None
    """Where the worker publishes; None: it publishes nothing (every frame goes back to the server)."""
    environ: dict[str, str] = field(default_factory=dict)
    """The server's environment, which the worker takes before anything else (`starter.py`: a
    forked worker has its fork server's); empty: the worker keeps its own."""


class CameraBuffers:
    """A camera's outputs as arrays over its shared memory block (`CameraSpec.layout`)."""

    def __init__(self, spec: CameraSpec, shm: SharedMemory) -> None:
        self.spec = spec
        self.shm = shm
        self.arrays: dict[str, Array] = {
            name: np.ndarray(shape, dtype=dtype, buffer=shm.buf, offset=offset)
            for name, (dtype, shape, offset) in spec.layout().items()
        }

    def drawn(self) -> dict[Raw, Array]:
        """The outputs a renderer draws straight into, by the raw buffer each takes."""
        return {kind.draws: self.arrays[kind.name] for kind in self.spec.kinds if kind.draws is not None}

    def release(self) -> None:
        """Drop the views first: a mapping with live views cannot be closed."""
        self.arrays.clear()


@dataclass
class _Camera:
    index: int
    buffers: CameraBuffers
    finishes: list[tuple[str, Finish]]
    """Each output's finishing step, in the order of the kinds (an output after those it needs)."""


def worker_main(conn: Connection, plan: WorkerPlan) -> None:
    """A render worker: load the scene, report ready, render requests until told to stop."""
    if plan.environ:
        take_environment(plan.environ)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the server's to handle; it closes the pool
    os.nice(10)
    _silence_stdio()
    try:
        from simbot.sim.bullet import pb

        scene = BulletScene(pb, plan.bodies)
        specs = {i: spec.rendered for i, (spec, _, _) in plan.jobs.items()}
        renderer, fallback = open_renderer(plan.renderer, scene, plan.light, specs, plan.gl_threads)
        held = _Held(scene, renderer, {}, None if plan.bus is None else FramePublisher(plan.bus))
        for index, (spec, name, publication) in plan.jobs.items():
            held.take_camera(index, spec, name, publication)
    except Exception as exc:
        conn.send(StartError(_reason(exc)))
        return
    conn.send(Ready(renderer.name, fallback, renderer.device))
    try:
        _serve(conn, held)
    finally:
        renderer.close()
        if held.publisher is not None:
            held.publisher.close()
        for camera in held.cameras.values():
            camera.buffers.release()
            camera.buffers.shm.close()
        scene.close()


def open_renderer(
    asked: str, scene: BulletScene, light: Light, cameras: Mapping[int, CameraSpec], gl_threads: int | None = None
) -> tuple[Renderer, str | None]:
    """The renderer asked for, and why `auto` fell back to TinyRenderer (None when it did not).
    An explicit `gl` that cannot open is an error: the user asked for it by name."""
    from simbot.sim.render.tiny import TinyRenderer

    if asked == "tiny":
        return TinyRenderer(scene, light, cameras), None
    try:
        from simbot.sim.render.gl import GlRenderer

        return GlRenderer(scene, light, cameras, gl_threads), None
    except Exception as exc:  # noqa: BLE001 - no moderngl, no libEGL, no GL 3.3: all mean "cannot use GL here"
        reason = f"no OpenGL 3.3 EGL context ({type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else 'no message'})"
        if asked == "gl":
            raise RuntimeError(f"--renderer gl: {reason}") from None
        return TinyRenderer(scene, light, cameras), reason


def _camera(index: int, spec: CameraSpec, shm_name: str) -> _Camera:
    return _Camera(index, CameraBuffers(spec, SharedMemory(name=shm_name)), _finishes(spec))


def _finishes(spec: CameraSpec) -> list[tuple[str, Finish]]:
    """Each output's finishing step, made anew (a noisy output's generator starts from the camera's seed)."""
    return [(kind.name, step) for kind in spec.kinds if kind.finisher and (step := kind.finisher(spec))]


@dataclass
class _Held:
    """What a worker holds, and the changes the pool may ask of it while the world runs."""

    scene: BulletScene
    renderer: Renderer
    cameras: dict[int, _Camera]
    publisher: FramePublisher | None
    """The worker's session on the bus, where it publishes its cameras' frames."""

    def take_camera(self, index: int, spec: CameraSpec, shm_name: str, publication: Publication | None) -> None:
        """A camera to render (its buffers in the pool's shared memory), and to publish where the server says."""
        self.cameras[index] = _camera(index, spec, shm_name)
        if publication is not None:
            if self.publisher is None:
                raise RuntimeError(f"camera {spec.name!r}: a publication, but no bus to publish it on")
            self.publisher.add(index, publication)

    def publish(self, request: RenderRequest) -> None:
        """The frame just finished, on the keys the request names (a camera without a publication: nothing)."""
        if self.publisher is not None:
            arrays = self.cameras[request.camera].buffers.arrays
            self.publisher.publish(request.camera, request.stamp_ns, arrays, request.publish)

    def change(self, change: SceneChange) -> None:
        """A change of the world that runs, each before any request sent after it."""
        match change:
            case AddCamera(index, spec, shm_name, publication):
                self.take_camera(index, spec, shm_name, publication)
                self.renderer.add_camera(index, spec.rendered)
            case UpdateCamera(index, spec):
                camera = self.cameras[index]
                camera.buffers.spec = spec
                camera.finishes = _finishes(spec)

    def edit(self, edit: EditScene) -> SceneEdited:
        """The world's edit applied whole (`pipe.EditScene`); what failed of it is reported, the rest stays applied."""
        failures = self.scene.edit(edit.removed, edit.added)
        loaded = [body.name for body in edit.added if body.name in self.scene.ids]
        self.renderer.edit(set(edit.removed), loaded, edit.light, edit.order)
        return SceneEdited(tuple(failures))


def _serve(conn: Connection, held: _Held) -> None:
    """The pool's messages in order until told to stop or the server is gone (EOF, broken pipe)."""
    try:
        while not isinstance(message := conn.recv(), Stop):
            if isinstance(message, RenderRequest):
                conn.send(_render_request(held, message))
                continue
            if isinstance(message, EditScene):
                conn.send(_edited(held, message))
                continue
            try:
                held.change(message)
            except Exception as exc:
                conn.send(SceneFailed(f"{message}: {_reason(exc)}"))
    except (EOFError, OSError):
        return


def _render_request(held: _Held, request: RenderRequest) -> FrameDone | RenderFailed:
    """The message that answers a request: its frame is done, or why it failed."""
    start = time.perf_counter()
    try:
        render(held.scene, held.renderer, held.cameras[request.camera], request.pose, request.states)
        held.publish(request)
    except Exception as exc:
        return RenderFailed(request.camera, request.stamp_ns, f"{type(exc).__name__}: {exc}")
    return FrameDone(request.camera, request.stamp_ns, time.perf_counter() - start)


def _edited(held: _Held, edit: EditScene) -> SceneEdited:
    try:
        return held.edit(edit)
    except Exception as exc:  # noqa: BLE001 - reported to the pool; the worker goes on
        return SceneEdited((f"{edit}: {_reason(exc)}",))


def _reason(exc: Exception) -> str:
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


def render(
    scene: BulletScene, renderer: Renderer, camera: _Camera, pose: Transform, states: Mapping[str, BodyState]
) -> None:
    """Pose the scene, draw (each view of a wide-angle camera: `wide_angle.views`), and finish the
    outputs in the camera's shared memory."""
    scene.apply(states)
    arrays = camera.buffers.arrays
    for view, drawn in views(camera.buffers.spec, pose, camera.buffers.drawn()):
        renderer.render(camera.index, view, drawn)
    for name, finish in camera.finishes:
        finish(arrays[name], arrays)


def _silence_stdio() -> None:
    """C code (PyBullet, Mesa) writes to fds 1 and 2 directly; the server's stdout and stderr are
    for its own output. Python's own tracebacks still reach the real stderr."""
    sys.stdout.flush()
    sys.stderr.flush()
    real_stderr = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    os.close(devnull)
    sys.stderr = open(real_stderr, "w", buffering=1, encoding="utf-8", errors="replace")  # noqa: SIM115 - for the process's life
