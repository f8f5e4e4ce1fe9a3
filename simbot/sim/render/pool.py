"""The pool of render worker processes, so that rendering never slows the physics.

- `RenderPool` starts worker processes (multiprocessing "spawn": the server has Zenoh threads,
  and forking a threaded process is unsafe). Each worker has its own PyBullet DIRECT client and
  loads the same scene as the server (the URDF texts the server loaded, at their start poses),
  and one renderer (`worker.py`). Cameras are dealt to the workers round-robin; a worker renders
  its cameras' requests in order.
- The world may change while the pool runs: `add_body` and `remove_body` go to every worker,
  `add_camera` to the worker with the fewest cameras (the camera takes the next index; the
  others keep theirs). A worker takes its messages in order, so a change reaches its scene
  before any request sent after it, and a set of requests sent together sees one scene. They
  return at once: a worker loads the body while the caller goes on, and one that cannot load it
  fails the next `collect`. (A worker busy with a frame reads the change when that frame is
  done, so sending a URDF text larger than a pipe holds waits for that frame.)
- Workers run at nice 10, so on a busy machine the physics wins the CPU and frames come late
  rather than the simulation slowing down.
- A request carries the camera's world pose and the poses and joint positions of the bodies that
  move; the worker sets its copy of the scene to them and renders. The camera's outputs (colour,
  depth, points: `kinds.py`) go back through shared memory, one block per camera; only a small message goes
  through the pipe.
- A camera given a `Publication` is published by its worker (`publishing.py`), which joins the
  bus as `bus` says: its pixels go from the worker's memory to the bus, and the frame handed over
  here is for what the server still does with it (counting it, `<save>`, bounding boxes). Which
  of its keys go out is said with each request (`publish`), by the server, which knows who listens.
- One request per camera may be outstanding: its shared memory holds one frame. Whether to skip a
  frame while the camera is busy (real time: the physics never waits) or to wait for it
  (lockstep: `collect(wait_for=i)`) is the caller's choice.

A frame's arrays are views of the camera's shared memory, valid until the next request for that
camera (copy them to keep them). `busy(i)` stays true until `collect` has handed camera i's frame
over, so a caller that only requests cameras that are not busy never overwrites pixels it has not
yet seen.

A worker that dies (a crash, a kill) breaks the pool rather than hanging it: collect() and
requests for its cameras raise RuntimeError naming the worker and its cameras; close() still works.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.shared_memory import SharedMemory
from types import MappingProxyType, TracebackType

from simbot.sim.render.pipe import (
    AddBody,
    AddCamera,
    FrameDone,
    Ready,
    RemoveBody,
    RenderFailed,
    RenderRequest,
    SceneChange,
    SceneFailed,
    StartError,
    Stop,
)
from simbot.sim.render.publishing import Bus, Publication
from simbot.sim.render.specs import BodyState, CameraSpec, Frame, Light, SceneBody
from simbot.sim.render.worker import RENDERERS, CameraBuffers, WorkerPlan, worker_main
from simbot.transform import Transform

log = logging.getLogger(__name__)

START_TIMEOUT_S = 60.0
"""How long a worker may take to load the scene (the warehouse's meshes take a few seconds)."""
STOP_GRACE_S = 0.5
"""How long close() lets a worker finish its current frame before terminating it."""


@dataclass(frozen=True)
class PoolPlan:
    """How many workers, and how many llvmpipe threads each."""

    workers: int
    gl_threads: int


def usable_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def plan_pool(
    cameras: int, asked_workers: int | None = None, cores: int | None = None, asked_threads: int | None = None
) -> PoolPlan:
    """A worker per core (a worker per camera at most), each with the rasterizer threads that every
    core but the physics' leaves it (on a GPU they are idle and cost nothing). Measured on two
    cores (benchmarks/bench_cameras.py, docs/speed.md): a worker's Python and vertex work is
    serial, so a second worker fills the core the physics leaves idle where a second llvmpipe
    thread waits on it; a third drew more in the warehouse alone but fewer in the main job, where
    the server and the clients want their share. At nice 10 the physics keeps real time.
    The workers and threads asked for, where asked."""
    usable = cores or usable_cores()
    workers = max(1, min(cameras, asked_workers or usable))
    return PoolPlan(workers, asked_threads or max(1, (usable - 1) // workers))


@dataclass
class _Worker:
    index: int
    process: BaseProcess
    conn: Connection
    cameras: list[int]
    death: str | None = None
    """Why it is gone, once it is."""


class RenderPool:
    """Renders camera frames in worker processes; see the module docstring."""

    renderer_used: str
    """"gl" or "tiny" ("gl" only when every worker got it)."""
    fallback_reason: str | None
    """Why `auto` fell back to TinyRenderer; None when it did not."""
    device: str
    """What draws: the GL renderer string (e.g. "llvmpipe (LLVM 15...)": Mesa on the CPU), or TinyRenderer."""

    def __init__(
        self,
        bodies: Sequence[SceneBody],
        cameras: Sequence[CameraSpec],
        workers: int,
        renderer: str = "auto",
        light: Light | None = None,
        start_timeout: float = START_TIMEOUT_S,
        gl_threads: int | None = None,
        bus: Bus | None = None,
        publications: Sequence[Publication | None] = (),
    ) -> None:
        """`publications`: what the workers publish of each camera (none: the caller publishes its frames)."""
        _check_config(bodies, cameras, workers, renderer)
        self.cameras = tuple(cameras)
        self._bus = bus
        self._publications = [*publications, *[None] * (len(self.cameras) - len(publications))]
        self._bodies: Mapping[str, SceneBody] = MappingProxyType({body.name: body for body in bodies})
        """Replaced, never changed, as bodies come and go: a frame keeps the scene it was requested in."""
        self._requested: dict[int, tuple[Transform, Mapping[str, BodyState], Mapping[str, SceneBody]]] = {}
        self._closed = False
        self._workers: list[_Worker] = []
        self._outstanding: dict[int, int] = {}  # camera -> stamp, until its frame is handed over
        self._finished: list[Frame] = []  # received, not yet handed over
        self._failures: list[str] = []
        self._shms = [SharedMemory(create=True, size=spec.nbytes) for spec in self.cameras]
        self._buffers = [CameraBuffers(spec, shm) for spec, shm in zip(self.cameras, self._shms, strict=True)]
        n = min(workers, len(self.cameras))
        self._worker_of = [i % n for i in range(len(self.cameras))] if n else []
        try:
            self._start(bodies, n, renderer, light or Light(), gl_threads)
            ready = self._await_ready(start_timeout)
        except BaseException:
            self.close()
            raise
        self._summarise(ready)
        log.info(
            "render pool: %d cameras on %d workers, renderer %s (%s)",
            len(self.cameras),
            n,
            self.renderer_used,
            self.device,
        )

    @property
    def pids(self) -> tuple[int | None, ...]:
        """The worker processes' ids, one per worker (for monitoring)."""
        return tuple(w.process.pid for w in self._workers)

    @property
    def body_names(self) -> frozenset[str]:
        """The bodies the workers' scenes hold (once they have read the changes sent)."""
        return frozenset(self._bodies)

    def add_body(self, body: SceneBody) -> None:
        """Every worker's scene loads `body` before any later request; see the module docstring."""
        self._check_open()
        if body.name in self._bodies:
            raise ValueError(f"body {body.name!r} is in the scene already")
        self._broadcast(AddBody(body))
        self._bodies = MappingProxyType({**self._bodies, body.name: body})

    def remove_body(self, name: str) -> None:
        """Every worker's scene drops body `name` before any later request."""
        self._check_open()
        if name not in self._bodies:
            raise ValueError(f"no body {name!r} in the scene")
        self._broadcast(RemoveBody(name))
        self._bodies = MappingProxyType({n: b for n, b in self._bodies.items() if n != name})

    def add_camera(self, spec: CameraSpec, publication: Publication | None = None) -> int:
        """A camera for the running pool, on the worker with the fewest cameras; its index (the next one)."""
        self._check_open()
        if not self._workers:
            raise RuntimeError(f"camera {spec.name!r}: a pool started with no cameras has no worker to render it")
        index = len(self.cameras)
        worker = min(self._workers, key=lambda w: len(w.cameras))
        shm = SharedMemory(create=True, size=spec.nbytes)
        self.cameras = (*self.cameras, spec)
        self._shms.append(shm)
        self._buffers.append(CameraBuffers(spec, shm))
        self._worker_of.append(worker.index)
        worker.cameras.append(index)
        self._publications.append(publication)
        self._send(worker, AddCamera(index, spec, shm.name, publication))
        return index

    def request(
        self,
        camera: int,
        stamp_ns: int,
        camera_pose: Transform,
        states: Mapping[str, BodyState],
        publish: Collection[str] = (),
    ) -> None:
        """Start rendering camera `camera` at the camera's world pose (looking along its +x, z up)
        with the moving bodies where `states` puts them, its worker then putting the keys of its
        publication in `publish` on the bus. Returns at once; raises if busy."""
        self._check_open()
        spec = self._spec(camera)
        worker = self._workers[self._worker_of[camera]]
        if worker.death is None and not worker.process.is_alive():
            self._drain(worker)
        if worker.death is not None:
            raise RuntimeError(f"camera {camera} {spec.name!r}: {worker.death}")
        if camera in self._outstanding:
            raise RuntimeError(f"camera {camera} {spec.name!r} is busy: collect its frame before requesting another")
        unknown = set(states) - set(self._bodies)
        if unknown:
            raise ValueError(f"camera {spec.name!r}: no such bodies in the scene: {sorted(unknown)}")
        pose, states = Transform.of(*camera_pose), dict(states)
        self._send(worker, RenderRequest(camera, int(stamp_ns), pose, states, frozenset(publish)))
        self._outstanding[camera] = int(stamp_ns)
        self._requested[camera] = (pose, states, self._bodies)

    def busy(self, camera: int) -> bool:
        """A request for `camera` is outstanding: from request() until collect() hands its frame over.
        False for a camera whose worker has died, so that request() raises rather than the camera
        being skipped forever in silence."""
        if camera not in self._outstanding:
            return False
        worker = self._workers[self._worker_of[camera]]
        return worker.death is None and worker.process.is_alive()

    def collect(self, wait_for: int | None = None, timeout: float | None = None) -> list[Frame]:
        """The frames finished since the last call, in the order they finished, without blocking.
        With `wait_for=i`, first waits (up to `timeout` s, TimeoutError after) for camera i's
        outstanding frame. Raises RuntimeError when a worker has died or a render failed."""
        self._check_open()
        for worker in self._workers:
            self._drain(worker)
        if wait_for is not None and wait_for in self._outstanding:
            self._wait(wait_for, timeout)
        return self._hand_over()

    def close(self) -> None:
        """Stop the workers (terminating one that does not finish its frame promptly) and free the
        shared memory. Idempotent."""
        if self._closed:
            return
        self._closed = True
        _stop_workers(self._workers)
        for buffers in self._buffers:
            buffers.release()
        self._finished.clear()
        self._outstanding.clear()
        for shm in self._shms:
            _free(shm)

    def __enter__(self) -> RenderPool:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    # --- starting

    def _start(self, bodies: Sequence[SceneBody], n: int, renderer: str, light: Light, gl_threads: int | None) -> None:
        ctx = multiprocessing.get_context("spawn")
        for index in range(n):
            mine = [i for i, w in enumerate(self._worker_of) if w == index]
            jobs = {i: (self.cameras[i], self._shms[i].name, self._publications[i]) for i in mine}
            parent_end, child_end = ctx.Pipe()
            process = ctx.Process(
                target=worker_main,
                args=(child_end, WorkerPlan(tuple(bodies), jobs, renderer, light, gl_threads, self._bus)),
                name=f"simbot-render-{index}",
                daemon=True,
            )
            process.start()
            child_end.close()  # so that the worker's death reads as EOF here
            self._workers.append(_Worker(index, process, parent_end, mine))

    def _await_ready(self, timeout: float) -> list[Ready]:
        """Every worker's ready message; a clear error when one fails, dies or takes too long."""
        deadline = time.monotonic() + timeout
        ready: dict[int, Ready] = {}
        while len(ready) < len(self._workers):
            waiting = [w for w in self._workers if w.index not in ready]
            left = deadline - time.monotonic()
            if left <= 0:
                names = ", ".join(self._camera_names(w) for w in waiting)
                raise RuntimeError(f"render workers did not load the scene within {timeout:.0f} s (cameras {names})")
            wait([h for w in waiting for h in (w.conn, w.process.sentinel)], left)
            for worker in waiting:
                message = self._poll_start(worker)
                if message is not None:
                    ready[worker.index] = message
        return [ready[w.index] for w in self._workers]

    def _poll_start(self, worker: _Worker) -> Ready | None:
        try:
            if not worker.conn.poll():
                if worker.process.is_alive():
                    return None
                raise EOFError
            message = worker.conn.recv()
        except (EOFError, OSError):
            self._mark_dead(worker)
            raise RuntimeError(f"render {worker.death} while loading the scene") from None
        if isinstance(message, StartError):
            raise RuntimeError(f"render worker {worker.index} failed to start: {message.reason}")
        assert isinstance(message, Ready), message  # a worker's first message is one of the two
        return message

    def _summarise(self, ready: list[Ready]) -> None:
        reasons = [r.fallback_reason for r in ready if r.fallback_reason]
        self.renderer_used = "gl" if ready and all(r.renderer == "gl" for r in ready) else "tiny"
        self.fallback_reason = reasons[0] if reasons else None
        self.device = ready[0].device if ready else "none"

    # --- receiving

    def _drain(self, worker: _Worker) -> None:
        """Take every message the worker has sent; notice its death."""
        if worker.death is not None:
            return
        exited = not worker.process.is_alive()  # asked first: what it sent before exiting is in the pipe
        try:
            while worker.conn.poll():
                self._receive(worker, worker.conn.recv())
        except (EOFError, OSError):
            exited = True
        if exited:
            self._mark_dead(worker)

    def _receive(self, worker: _Worker, message: FrameDone | RenderFailed | SceneFailed) -> None:
        match message:
            case FrameDone(camera, stamp, render_s):
                pose, states, bodies = self._requested.pop(camera)
                arrays = dict(self._buffers[camera].arrays)
                self._finished.append(Frame(camera, stamp, arrays, render_s, pose, states, bodies))
            case RenderFailed(camera, stamp, reason):
                del self._outstanding[camera]
                self._requested.pop(camera, None)
                self._failures.append(f"camera {camera} {self.cameras[camera].name!r} at {stamp} ns: {reason}")
            case SceneFailed(reason):
                self._failures.append(f"render worker {worker.index}: {reason}")

    def _wait(self, camera: int, timeout: float | None) -> None:
        """Block until camera's frame (or its failure) has arrived."""
        worker = self._workers[self._worker_of[camera]]
        deadline = None if timeout is None else time.monotonic() + timeout
        while camera in self._outstanding and not any(f.camera == camera for f in self._finished):
            if worker.death is not None:
                raise RuntimeError(f"camera {camera} {self.cameras[camera].name!r}: {worker.death}")
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise TimeoutError(f"camera {camera} {self.cameras[camera].name!r}: no frame within {timeout} s")
            wait([worker.conn, worker.process.sentinel], left)
            self._drain(worker)

    def _hand_over(self) -> list[Frame]:
        if self._failures:
            failures, self._failures = self._failures, []
            raise RuntimeError("render failed: " + "; ".join(failures))
        dead = [w.death for w in self._workers if w.death is not None]
        if dead:
            raise RuntimeError(dead[0])
        frames, self._finished = self._finished, []
        for frame in frames:
            del self._outstanding[frame.camera]
        return frames

    # --- sending

    def _broadcast(self, message: SceneChange) -> None:
        """To every live worker; a dead one's cameras raise at their next request."""
        for worker in self._workers:
            if worker.death is None:
                with contextlib.suppress(RuntimeError):
                    self._send(worker, message)

    def _send(self, worker: _Worker, message: RenderRequest | SceneChange) -> None:
        """RuntimeError naming the worker and its cameras when it is gone."""
        try:
            worker.conn.send(message)
        except OSError:
            self._mark_dead(worker)
            raise RuntimeError(worker.death) from None

    def _mark_dead(self, worker: _Worker) -> None:
        if worker.death is not None:
            return
        worker.process.join(1.0)
        code = worker.process.exitcode
        how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        worker.death = (
            f"render worker {worker.index} (pid {worker.process.pid}) died ({how}); "
            f"its cameras: {self._camera_names(worker)}"
        )
        log.error("%s", worker.death)  # also raised to the caller; logged here in case it swallows that

    def _spec(self, camera: int) -> CameraSpec:
        if not 0 <= camera < len(self.cameras):
            raise IndexError(f"camera {camera}: the pool has cameras 0..{len(self.cameras) - 1}")
        return self.cameras[camera]

    def _camera_names(self, worker: _Worker) -> str:
        return ", ".join(self.cameras[i].name for i in worker.cameras)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("render pool is closed")


def _check_config(bodies: Sequence[SceneBody], cameras: Sequence[CameraSpec], workers: int, renderer: str) -> None:
    if renderer not in RENDERERS:
        raise ValueError(f"renderer {renderer!r}: expected one of {RENDERERS}")
    if workers < 1:
        raise ValueError(f"workers {workers}: at least one")
    names = [body.name for body in bodies]
    if len(set(names)) != len(names):
        raise ValueError(f"body names must be unique: {names}")


def _stop_workers(workers: Sequence[_Worker]) -> None:
    """Ask politely, give a frame's time, then terminate, then kill: every worker at each stage
    together, so that stopping takes the same time however many workers there are."""
    for worker in workers:
        with contextlib.suppress(OSError):  # a dead worker's pipe: it is stopped already
            worker.conn.send(Stop())
    _join_all(workers, STOP_GRACE_S)
    for stage, seconds in ((BaseProcess.terminate, 1.0), (BaseProcess.kill, None)):
        alive = [worker for worker in workers if worker.process.is_alive()]
        for worker in alive:
            stage(worker.process)
        _join_all(alive, seconds)
    for worker in workers:
        worker.conn.close()


def _join_all(workers: Sequence[_Worker], seconds: float | None) -> None:
    """Waits for the workers to end, `seconds` for all of them together (None: as long as it takes)."""
    deadline = None if seconds is None else time.monotonic() + seconds
    for worker in workers:
        worker.process.join(None if deadline is None else max(0.0, deadline - time.monotonic()))


def _free(shm: SharedMemory) -> None:
    """Unlink the block; unmap it unless a caller still holds a frame's pixels (then the mapping
    goes when they do)."""
    try:
        shm.close()
    except BufferError:
        log.debug("shared memory %s still viewed by a caller's frame; unmapped when that goes", shm.name)
    with contextlib.suppress(FileNotFoundError):
        shm.unlink()
