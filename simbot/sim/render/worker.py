"""A render worker process: its own copy of the scene, one renderer, requests in order.

The worker loads the scene (`BulletScene`), opens the renderer it was asked for (`gl`, `tiny`, or
`auto`: gl when an EGL context opens, else tiny with the reason), reports ready, then takes the
pool's messages in order until told to stop or the server is gone: render requests, and the
changes of a world that runs (a body added or removed, a camera added), each before any request
sent after it. Each frame is drawn straight into the camera's shared memory and finished there
(`outputs.py`); only a small message goes back. A change that fails is reported (`scene_failed`)
and the worker goes on.
"""

from __future__ import annotations

import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any, Protocol

import numpy as np

from simbot.sim.render.outputs import PointGrid, add_noise, linear_depth
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.specs import BodyState, CameraSpec, Depths, Light, Pixels, Points, SceneBody, Transform

RENDERERS = ("auto", "gl", "tiny")


class Renderer(Protocol):
    name: str
    device: str

    def render(self, camera: int, pose: Transform, color: Pixels | None, depth: Depths | None) -> None: ...

    def add_camera(self, index: int, spec: CameraSpec) -> None: ...

    def add_body(self, name: str) -> None:
        """After the scene has loaded it."""
        ...

    def remove_body(self, name: str) -> None:
        """Before the scene drops it."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class WorkerPlan:
    """What a worker is asked to do."""

    bodies: tuple[SceneBody, ...]
    jobs: dict[int, tuple[CameraSpec, str]]
    """Camera index → (spec, shared memory name)."""
    renderer: str
    light: Light
    gl_threads: int | None
    """LP_NUM_THREADS for Mesa's llvmpipe (None: Mesa's default, one per core)."""


class CameraBuffers:
    """A camera's outputs as arrays over its shared memory block (`CameraSpec.layout`)."""

    def __init__(self, spec: CameraSpec, shm: SharedMemory) -> None:
        self.spec = spec
        self.shm = shm
        self.arrays: dict[str, Any] = {
            name: np.ndarray(shape, dtype=dtype, buffer=shm.buf, offset=offset)
            for name, (dtype, shape, offset) in spec.layout().items()
        }

    @property
    def color(self) -> Pixels | None:
        return self.arrays.get("color")

    @property
    def depth(self) -> Depths | None:
        return self.arrays.get("depth")

    @property
    def points(self) -> Points | None:
        return self.arrays.get("points")

    def release(self) -> None:
        """Drop the views first: a mapping with live views cannot be closed."""
        self.arrays.clear()


@dataclass
class _Camera:
    index: int
    buffers: CameraBuffers
    rng: np.random.Generator
    grid: PointGrid | None


def worker_main(conn: Connection, plan: WorkerPlan) -> None:
    """A render worker: load the scene, report ready, render requests until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the server's to handle; it closes the pool
    os.nice(10)
    _silence_stdio()
    try:
        from simbot.sim.physics.bullet import pb

        scene = BulletScene(pb, plan.bodies)
        specs = {i: spec for i, (spec, _) in plan.jobs.items()}
        renderer, fallback = open_renderer(plan.renderer, scene, plan.light, specs, plan.gl_threads)
        held = _Held(scene, renderer, {i: _camera(i, spec, name) for i, (spec, name) in plan.jobs.items()})
    except Exception as exc:
        conn.send(("error", _reason(exc)))
        return
    conn.send(("ready", renderer.name, fallback, renderer.device))
    try:
        _serve(conn, held)
    finally:
        renderer.close()
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
    buffers = CameraBuffers(spec, SharedMemory(name=shm_name))
    return _Camera(index, buffers, np.random.default_rng(spec.seed), PointGrid(spec) if spec.points else None)


@dataclass
class _Held:
    """What a worker holds, and the changes the pool may ask of it while the world runs."""

    scene: BulletScene
    renderer: Renderer
    cameras: dict[int, _Camera]

    def add_body(self, body: SceneBody) -> None:
        self.scene.add(body)
        self.renderer.add_body(body.name)

    def remove_body(self, name: str) -> None:
        self.renderer.remove_body(name)
        self.scene.remove(name)

    def add_camera(self, index: int, spec: CameraSpec, shm_name: str) -> None:
        self.cameras[index] = _camera(index, spec, shm_name)
        self.renderer.add_camera(index, spec)


def _serve(conn: Connection, held: _Held) -> None:
    """The pool's messages in order until told to stop or the server is gone (EOF, broken pipe)."""
    changes: dict[str, Callable[..., None]] = {
        "add_body": held.add_body,
        "remove_body": held.remove_body,
        "add_camera": held.add_camera,
    }
    try:
        while (message := conn.recv())[0] != "stop":
            kind, *args = message
            if kind == "render":
                conn.send(_render_request(held, *args))
                continue
            try:
                changes[kind](*args)
            except Exception as exc:
                subject = getattr(args[0], "name", args[0])  # a SceneBody by its name; a body name; a camera index
                conn.send(("scene_failed", f"{kind} {subject!r}: {_reason(exc)}"))
    except (EOFError, OSError):
        return


def _render_request(
    held: _Held, camera: int, stamp: int, pose: Transform, states: Mapping[str, BodyState]
) -> tuple[Any, ...]:
    """The message that answers a request: its frame is done, or why it failed."""
    start = time.perf_counter()
    try:
        render(held.scene, held.renderer, held.cameras[camera], pose, states)
    except Exception as exc:
        return ("failed", camera, stamp, f"{type(exc).__name__}: {exc}")
    return ("frame", camera, stamp, time.perf_counter() - start)


def _reason(exc: Exception) -> str:
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


def render(
    scene: BulletScene, renderer: Renderer, camera: _Camera, pose: Transform, states: Mapping[str, BodyState]
) -> None:
    """Pose the scene, draw, and finish the outputs in the camera's shared memory."""
    scene.apply(states)
    buffers = camera.buffers
    spec = buffers.spec
    color, depth = buffers.color, buffers.depth
    renderer.render(camera.index, pose, color, depth)
    if depth is not None:
        linear_depth(depth, spec.near, spec.far)
    if color is not None and spec.noise_stddev > 0.0:
        add_noise(color, spec.noise_stddev, camera.rng)
    if camera.grid is not None and depth is not None and color is not None and buffers.points is not None:
        camera.grid.fill(depth, color, buffers.points)


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
