"""The pool of render worker processes, so that rendering never slows the physics.

- `RenderPool` starts worker processes, forked from a fork server that has done their imports
  once (`starter.py`; the server itself, with Zenoh's threads, is never forked). Each worker has
  its own PyBullet DIRECT client and loads the same scene as the server (the URDF texts the
  server loaded, at their start poses), and one renderer (`worker.py`). Cameras are dealt to the
  workers round-robin; a worker renders its cameras' requests in order.
- The world may change while the pool runs, and the pool runs on: `edit` (bodies out, bodies in,
  a body replaced, the lighting; `add_body` and `remove_body` are edits of one body) goes to
  every worker, which applies it whole and rebuilds what it batches once; `add_camera` goes to
  the worker with the fewest cameras (the camera takes the next index; the others keep theirs);
  `update_camera` changes a camera's noise. A worker takes its messages in order, so a change
  reaches its scene before any request sent after it, and a set of requests sent together sees
  one scene. They return at once: a worker applies the edit while the caller goes on, and a body
  that cannot be loaded fails the next `collect`. (A worker busy with a frame reads the change
  when that frame is done, so sending a URDF text larger than a pipe holds waits for that frame.)
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
One that dies while it applies an edit (one sent, not yet answered) is started again on the
scene as edited, with a warning: the frames it owed are dropped (`dropped`, the caller counts
them skipped), and the pool goes on.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from multiprocessing.connection import wait
from multiprocessing.shared_memory import SharedMemory
from types import MappingProxyType, TracebackType

from simbot.sim.render import pool_workers, starter
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
    UpdateCamera,
)
from simbot.sim.render.pool_workers import Worker
from simbot.sim.render.publishing import Bus, Publication
from simbot.sim.render.specs import BodyState, CameraSpec, Frame, Light, SceneBody
from simbot.sim.render.worker import RENDERERS, CameraBuffers, WorkerPlan
from simbot.transform import Transform

log = logging.getLogger(__name__)

START_TIMEOUT_S = 60.0
"""How long a worker may take to load the scene (the warehouse's meshes take a few seconds)."""


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
        self._renderer, self._gl_threads, self._light = renderer, gl_threads, light or Light()
        self._start_timeout = start_timeout
        self._publications = [*publications, *[None] * (len(self.cameras) - len(publications))]
        self._bodies: Mapping[str, SceneBody] = MappingProxyType({body.name: body for body in bodies})
        """In the scene's order; replaced, never changed, as bodies come and go: a frame keeps the scene it was requested in."""
        self._requested: dict[int, tuple[Transform, Mapping[str, BodyState], Mapping[str, SceneBody]]] = {}
        self._closed = False
        self._workers: list[Worker] = []
        self._outstanding: dict[int, int] = {}  # camera -> stamp, until its frame is handed over
        self._finished: list[Frame] = []  # received, not yet handed over
        self._failures: list[str] = []
        self._dropped: list[int] = []
        self._shms = [SharedMemory(create=True, size=spec.nbytes) for spec in self.cameras]
        self._buffers = [CameraBuffers(spec, shm) for spec, shm in zip(self.cameras, self._shms, strict=True)]
        n = min(workers, len(self.cameras))
        self._worker_of = [i % n for i in range(len(self.cameras))] if n else []
        try:
            for index in range(n):
                mine = [i for i, w in enumerate(self._worker_of) if w == index]
                self._workers.append(Worker(index, *pool_workers.launch(index, self._plan(mine)), mine))
            ready = pool_workers.await_ready(
                self._workers, start_timeout, {w.index: self._camera_names(w) for w in self._workers}
            )
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

    def exited(self, worker: int) -> bool:
        """Whether worker `worker` has ended, as its handle tells (its parent may be the fork server)."""
        return not self._workers[worker].process.is_alive()

    @property
    def body_names(self) -> frozenset[str]:
        """The bodies the workers' scenes hold (once they have read the changes sent)."""
        return frozenset(self._bodies)

    def edit(
        self,
        removed: Iterable[str] = (),
        added: Iterable[SceneBody] = (),
        light: Light | None = None,
        order: Sequence[str] | None = None,
    ) -> None:
        """Every worker's scene takes the edit whole before any later request (`pipe.EditScene`):
        the bodies `removed` out, then those `added` in (a name in both: the body replaced), the
        lighting where given, the bodies in `order` (default: as they were, the new ones after)."""
        self._check_open()
        removed, added = tuple(removed), tuple(added)
        unknown = [name for name in removed if name not in self._bodies]
        if unknown:
            raise ValueError(f"no body {unknown[0]!r} in the scene")
        bodies = {name: body for name, body in self._bodies.items() if name not in removed}
        clash = [body.name for body in added if body.name in bodies]
        if clash:
            raise ValueError(f"body {clash[0]!r} is in the scene already")
        bodies |= {body.name: body for body in added}
        order = tuple(bodies) if order is None else tuple(order)
        if sorted(order) != sorted(bodies):
            raise ValueError(f"order {list(order)} does not name the scene's bodies {sorted(bodies)}")
        edit = EditScene(removed, added, None if light == self._light else light, order)
        self._bodies = MappingProxyType({name: bodies[name] for name in order})
        self._light = light or self._light
        for worker in self._workers:
            if worker.death is None:
                worker.edits += 1
        self._broadcast(edit)

    def add_body(self, body: SceneBody) -> None:
        """Every worker's scene loads `body` before any later request; see the module docstring."""
        self.edit(added=(body,))

    def remove_body(self, name: str) -> None:
        """Every worker's scene drops body `name` before any later request."""
        self.edit(removed=(name,))

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

    def update_camera(self, camera: int, spec: CameraSpec) -> None:
        """Camera `camera` renders as `spec` says from its next request: its noise and its seed may
        change (its noise starts again from the seed), nothing else. ValueError otherwise."""
        self._check_open()
        old = self._spec(camera)
        if replace(spec, noise_stddev=old.noise_stddev, seed=old.seed) != old:
            raise ValueError(f"camera {camera} {old.name!r}: only its noise may change in a running pool")
        self.cameras = (*self.cameras[:camera], spec, *self.cameras[camera + 1 :])
        self._buffers[camera].spec = spec
        self._send(self._workers[self._worker_of[camera]], UpdateCamera(camera, spec))

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
        return self._workers[self._worker_of[camera]].alive

    def collect(self, wait_for: int | None = None, timeout: float | None = None) -> list[Frame]:
        """The frames finished since the last call, in the order they finished, without blocking.
        With `wait_for=i`, first waits (up to `timeout` s, TimeoutError after) for camera i's
        outstanding frame (none where it was dropped). Raises RuntimeError when a worker has died
        or a render failed."""
        self._check_open()
        for worker in self._workers:
            self._drain(worker)
        if wait_for is not None and wait_for in self._outstanding:
            self._wait(wait_for, timeout)
        return self._hand_over()

    def dropped(self) -> list[int]:
        """The cameras whose requested frames were dropped since the last call (a worker that died
        during an edit and was started again): the caller counts them skipped."""
        dropped, self._dropped = self._dropped, []
        return dropped

    def close(self) -> None:
        """Stop the workers (terminating one that does not finish its frame promptly) and free the
        shared memory. Idempotent."""
        if self._closed:
            return
        self._closed = True
        pool_workers.stop(self._workers)
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

    def _plan(self, cameras: list[int]) -> WorkerPlan:
        """What a worker of these cameras loads: the scene as it is now, the cameras as they are now."""
        jobs = {i: (self.cameras[i], self._shms[i].name, self._publications[i]) for i in cameras}
        return WorkerPlan(
            tuple(self._bodies.values()),
            jobs,
            self._renderer,
            self._light,
            self._gl_threads,
            self._bus,
            starter.environment(),
        )

    def _summarise(self, ready: list[Ready]) -> None:
        reasons = [r.fallback_reason for r in ready if r.fallback_reason]
        self.renderer_used = "gl" if ready and all(r.renderer == "gl" for r in ready) else "tiny"
        self.fallback_reason = reasons[0] if reasons else None
        self.device = ready[0].device if ready else "none"

    def _restart(self, worker: Worker) -> bool:
        """A worker that died during an edit, started again on the scene as edited; the frames it
        owed are dropped. False where it does not start (it stays dead)."""
        why = pool_workers.death(worker, self._camera_names(worker))
        owed = [camera for camera in worker.cameras if camera in self._outstanding]
        worker.conn.close()
        try:
            worker.process, worker.conn = pool_workers.launch(worker.index, self._plan(worker.cameras))
            worker.edits = 0
            pool_workers.await_ready([worker], self._start_timeout, {worker.index: self._camera_names(worker)})
        except RuntimeError as exc:
            log.error("%s during a scene edit, and did not start again: %s", why, exc)
            return False
        for camera in owed:
            del self._outstanding[camera]
            self._requested.pop(camera, None)
        self._finished = [frame for frame in self._finished if frame.camera not in owed]
        self._dropped += owed
        log.warning("%s during a scene edit; started again (pid %s), frames dropped: %s", why, worker.process.pid, owed)
        return True

    # --- receiving

    def _drain(self, worker: Worker) -> None:
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
            self._lost(worker)

    def _receive(self, worker: Worker, message: FrameDone | RenderFailed | SceneEdited | SceneFailed) -> None:
        match message:
            case FrameDone(camera, stamp, render_s):
                pose, states, bodies = self._requested.pop(camera)
                arrays = dict(self._buffers[camera].arrays)
                self._finished.append(Frame(camera, stamp, arrays, render_s, pose, states, bodies))
            case RenderFailed(camera, stamp, reason):
                del self._outstanding[camera]
                self._requested.pop(camera, None)
                self._failures.append(f"camera {camera} {self.cameras[camera].name!r} at {stamp} ns: {reason}")
            case SceneEdited(failures):
                worker.edits -= 1
                self._failures += [f"render worker {worker.index}: {failure}" for failure in failures]
            case SceneFailed(reason):
                self._failures.append(f"render worker {worker.index}: {reason}")

    def _wait(self, camera: int, timeout: float | None) -> None:
        """Block until camera's frame (or its failure, or its drop) has arrived."""
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

    def _send(self, worker: Worker, message: RenderRequest | SceneChange) -> None:
        """RuntimeError naming the worker and its cameras when it is gone (one started again after
        dying during an edit has the scene as edited, and takes the message)."""
        try:
            worker.conn.send(message)
        except OSError:
            if not self._lost(worker):
                raise RuntimeError(worker.death) from None
            if isinstance(message, RenderRequest):  # its plan held the scene and cameras as they are now
                worker.conn.send(message)

    def _lost(self, worker: Worker) -> bool:
        """A worker found gone: started again where it died during an edit (True), else marked dead."""
        if worker.death is not None:
            return False
        if worker.edits > 0 and not self._closed and self._restart(worker):
            return True
        worker.death = pool_workers.death(worker, self._camera_names(worker))
        log.error("%s", worker.death)  # also raised to the caller; logged here in case it swallows that
        return False

    def _spec(self, camera: int) -> CameraSpec:
        if not 0 <= camera < len(self.cameras):
            raise IndexError(f"camera {camera}: the pool has cameras 0..{len(self.cameras) - 1}")
        return self.cameras[camera]

    def _camera_names(self, worker: Worker) -> str:
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


def _free(shm: SharedMemory) -> None:
    """Unlink the block; unmap it unless a caller still holds a frame's pixels (then the mapping
    goes when they do)."""
    try:
        shm.close()
    except BufferError:
        log.debug("shared memory %s still viewed by a caller's frame; unmapped when that goes", shm.name)
    with contextlib.suppress(FileNotFoundError):
        shm.unlink()
