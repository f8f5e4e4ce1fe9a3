"""Camera rendering in worker processes, so that rendering never slows the physics.

PyBullet's TinyRenderer takes tens of milliseconds per 640 × 480 frame on one core, and six
cameras at 30 Hz would need several cores' worth of it. The physics process cannot afford a
single one, so rendering runs elsewhere:

- `RenderPool` starts worker processes (multiprocessing "spawn": the server has Zenoh threads,
  and forking a threaded process is unsafe). Each worker has its own PyBullet DIRECT client and
  loads the same scene as the server (the URDF texts the server loaded, at their start poses).
  Cameras are dealt to the workers round-robin; a worker renders its cameras' requests in order.
- Workers run at nice 10, so on a busy machine the physics wins the CPU and frames come late
  rather than the simulation slowing down. They keep PyBullet's chatter off the server's stdout
  and stderr (the C code prints there directly, so it is silenced at the file-descriptor level).
- A request carries the camera's world pose and the poses and joint positions of the bodies that
  move; the worker sets its copy of the scene to them and renders. The pixels go back through
  shared memory, one block per camera; only a small message goes through the pipe.
- One request per camera may be outstanding: its shared memory holds one frame. Whether to skip a
  frame while the camera is busy (real time: the physics never waits) or to wait for it
  (lockstep: `collect(wait_for=i)`) is the caller's choice.

A frame's pixels are a view of the camera's shared memory, valid until the next request for that
camera (copy them to keep them). `busy(i)` stays true until `collect` has handed camera i's frame
over, so a caller that only requests cameras that are not busy never overwrites pixels it has not
yet seen.

A worker that dies (a crash, a kill) breaks the pool rather than hanging it: collect() and
requests for its cameras raise RuntimeError naming the worker and its cameras; close() still works.
"""

from __future__ import annotations

import ctypes
import importlib.util
import logging
import math
import multiprocessing
import os
import re
import signal
import sys
import tempfile
import time
import traceback
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.shared_memory import SharedMemory
from types import ModuleType, TracebackType
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

log = logging.getLogger(__name__)

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Transform = tuple[Vec3, Quat]
"""(xyz, quaternion xyzw): PyBullet's form."""

Pixels = npt.NDArray[np.uint8]

RENDERERS = ("tiny", "egl")
START_TIMEOUT_S = 60.0
"""How long a worker may take to load the scene (the warehouse's meshes take a few seconds)."""
STOP_GRACE_S = 0.5
"""How long close() lets a worker finish its current frame before terminating it."""
LUMA = (0.299, 0.587, 0.114)
"""ITU-R BT.601 luminance weights, as OpenCV's RGB2GRAY and Gazebo's L8 conversion."""


@dataclass(frozen=True)
class SceneBody:
    """A body as the server loaded it, for the workers to load the same way."""

    name: str
    urdf: str
    """URDF text as PyBullet loaded it in the server (mesh paths absolute)."""
    static: bool
    """loadURDF(useFixedBase=static)."""
    base: Transform
    """PyBullet base (centre-of-mass) pose at start, as getBasePositionAndOrientation gives it."""


@dataclass(frozen=True)
class BodyState:
    """Where a moving body is at the instant a frame is taken."""

    base: Transform
    """PyBullet base pose (centre-of-mass frame), raw from getBasePositionAndOrientation."""
    joints: tuple[float, ...]
    """Position of every joint in PyBullet joint index order (fixed joints included, value 0)."""


@dataclass(frozen=True)
class CameraSpec:
    """A camera's intrinsics and image format; the pose comes with each request."""

    name: str
    width: int
    height: int
    hfov: float
    """Horizontal field of view, radians; pixels are square, so fx = fy = (width/2)/tan(hfov/2)."""
    near: float
    far: float
    channels: int = 3
    """3: RGB (rgb8); 1: luminance (mono8)."""
    noise_stddev: float = 0.0
    """Gaussian pixel noise in units of full scale, as SDF camera noise (0..1)."""
    seed: int = 0

    def __post_init__(self) -> None:
        """Fail at configuration, not in a worker."""
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera {self.name!r}: image size {self.width}x{self.height} must be positive")
        if not 0.0 < self.hfov < math.pi:
            raise ValueError(f"camera {self.name!r}: horizontal fov {self.hfov} must be in (0, pi)")
        if not 0.0 < self.near < self.far:
            raise ValueError(f"camera {self.name!r}: clip near {self.near} / far {self.far} must be 0 < near < far")
        if self.channels not in (1, 3):
            raise ValueError(f"camera {self.name!r}: channels {self.channels} must be 1 (mono8) or 3 (rgb8)")
        if not self.noise_stddev >= 0.0:
            raise ValueError(f"camera {self.name!r}: noise stddev {self.noise_stddev} must be >= 0")

    @property
    def shape(self) -> tuple[int, ...]:
        """The image array's shape: H×W×3, or H×W for mono."""
        return (self.height, self.width, 3) if self.channels == 3 else (self.height, self.width)

    @property
    def nbytes(self) -> int:
        return self.width * self.height * self.channels

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view in degrees, as computeProjectionMatrixFOV wants it."""
        return math.degrees(2.0 * math.atan(math.tan(self.hfov / 2.0) * self.height / self.width))

    @property
    def fx(self) -> float:
        """Focal length in pixels (fx = fy)."""
        return (self.width / 2.0) / math.tan(self.hfov / 2.0)


@dataclass(frozen=True)
class Light:
    """TinyRenderer's directional light. ambient + diffuse = 1, so a face that looks at the light
    shows its material colour exactly (no clipping, hue kept) and faces away from it keep 60 % of
    it. No specular term: its highlight depends on the view and adds nothing for perception."""

    direction: Vec3 = (-0.5, 0.1, -0.9)
    """Direction the light travels, world frame (SDF <direction>); PyBullet wants the opposite."""
    ambient: float = 0.6
    diffuse: float = 0.4
    specular: float = 0.0
    color: Vec3 = (1.0, 1.0, 1.0)


class Frame(NamedTuple):
    """A rendered frame. `pixels` is a view of the camera's shared memory, valid until the next
    request for that camera."""

    camera: int
    stamp_ns: int
    pixels: Pixels
    render_s: float
    """Seconds the worker spent on it (scene update, render, conversion, copy)."""


@dataclass
class _Worker:
    index: int
    process: BaseProcess
    conn: Connection
    cameras: tuple[int, ...]
    death: str | None = None
    """Why it is gone, once it is."""


@dataclass
class _Ready:
    renderer: str
    fallback_reason: str | None
    gl_renderer: str | None


class RenderPool:
    """Renders camera frames in worker processes; see the module docstring."""

    renderer_used: str
    """"tiny" or "egl" ("egl" only when every worker got it)."""
    fallback_reason: str | None
    """Why "egl" was asked for and not used; None when it was used or not asked for."""
    gl_renderer: str | None
    """The GL renderer the EGL plugin reported (e.g. "llvmpipe (LLVM 15...)": software EGL)."""

    def __init__(
        self,
        bodies: Sequence[SceneBody],
        cameras: Sequence[CameraSpec],
        workers: int,
        renderer: str = "tiny",
        light: Light = Light(),
        start_timeout: float = START_TIMEOUT_S,
    ) -> None:
        _check_config(bodies, cameras, workers, renderer)
        self.cameras = tuple(cameras)
        self._body_names = frozenset(body.name for body in bodies)
        self._closed = False
        self._workers: list[_Worker] = []
        self._outstanding: dict[int, int] = {}  # camera -> stamp, until its frame is handed over
        self._finished: list[Frame] = []  # received, not yet handed over
        self._failures: list[str] = []
        self._shms = [SharedMemory(create=True, size=spec.nbytes) for spec in self.cameras]
        self._views: list[Pixels] = [
            np.ndarray(spec.shape, dtype=np.uint8, buffer=shm.buf) for spec, shm in zip(self.cameras, self._shms)
        ]
        n = min(workers, len(self.cameras))
        self._worker_of = [i % n for i in range(len(self.cameras))] if n else []
        try:
            self._start(bodies, n, renderer, light)
            ready = self._await_ready(start_timeout)
        except BaseException:
            self.close()
            raise
        self._summarise(ready, renderer)
        log.info(
            "render pool: %d cameras on %d workers, renderer %s%s",
            len(self.cameras), n, self.renderer_used, f" ({self.gl_renderer})" if self.gl_renderer else "",
        )

    @property
    def pids(self) -> tuple[int | None, ...]:
        """The worker processes' ids, one per worker (for monitoring)."""
        return tuple(w.process.pid for w in self._workers)

    def request(self, camera: int, stamp_ns: int, camera_pose: Transform, states: Mapping[str, BodyState]) -> None:
        """Start rendering camera `camera` at the camera's world pose (looking along its +x, z up)
        with the moving bodies where `states` puts them. Returns at once; raises if busy."""
        self._check_open()
        spec = self._spec(camera)
        worker = self._workers[self._worker_of[camera]]
        if worker.death is None and not worker.process.is_alive():
            self._drain(worker)
        if worker.death is not None:
            raise RuntimeError(f"camera {camera} {spec.name!r}: {worker.death}")
        if camera in self._outstanding:
            raise RuntimeError(f"camera {camera} {spec.name!r} is busy: collect its frame before requesting another")
        unknown = set(states) - self._body_names
        if unknown:
            raise ValueError(f"camera {spec.name!r}: no such bodies in the scene: {sorted(unknown)}")
        pos, quat = camera_pose
        pose = (tuple(float(v) for v in pos), tuple(float(v) for v in quat))
        try:
            worker.conn.send(("render", camera, int(stamp_ns), pose, dict(states)))
        except OSError:
            self._mark_dead(worker)
            raise RuntimeError(f"camera {camera} {spec.name!r}: {worker.death}") from None
        self._outstanding[camera] = int(stamp_ns)

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
        self._views.clear()
        self._finished.clear()
        self._outstanding.clear()
        for shm in self._shms:
            _free(shm)

    def __enter__(self) -> RenderPool:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    # --- starting

    def _start(self, bodies: Sequence[SceneBody], n: int, renderer: str, light: Light) -> None:
        ctx = multiprocessing.get_context("spawn")
        for index in range(n):
            mine = tuple(i for i, w in enumerate(self._worker_of) if w == index)
            jobs = {i: (self.cameras[i], self._shms[i].name) for i in mine}
            parent_end, child_end = ctx.Pipe()
            process = ctx.Process(
                target=_worker_main,
                args=(child_end, tuple(bodies), jobs, renderer, light),
                name=f"simbot-render-{index}",
                daemon=True,
            )
            process.start()
            child_end.close()  # so that the worker's death reads as EOF here
            self._workers.append(_Worker(index, process, parent_end, mine))

    def _await_ready(self, timeout: float) -> list[_Ready]:
        """Every worker's ready message; a clear error when one fails, dies or takes too long."""
        deadline = time.monotonic() + timeout
        ready: dict[int, _Ready] = {}
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

    def _poll_start(self, worker: _Worker) -> _Ready | None:
        try:
            if not worker.conn.poll():
                if worker.process.is_alive():
                    return None
                raise EOFError
            message = worker.conn.recv()
        except (EOFError, OSError):
            self._mark_dead(worker)
            raise RuntimeError(f"render {worker.death} while loading the scene") from None
        if message[0] == "error":
            raise RuntimeError(f"render worker {worker.index} failed to start: {message[1]}")
        _, renderer, reason, gl = message
        return _Ready(renderer, reason, gl)

    def _summarise(self, ready: list[_Ready], asked: str) -> None:
        reasons = [r.fallback_reason for r in ready if r.fallback_reason]
        self.renderer_used = "egl" if ready and all(r.renderer == "egl" for r in ready) else "tiny"
        self.fallback_reason = reasons[0] if asked == "egl" and reasons else None
        self.gl_renderer = next((r.gl_renderer for r in ready if r.gl_renderer), None)

    # --- receiving

    def _drain(self, worker: _Worker) -> None:
        """Take every message the worker has sent; notice its death."""
        if worker.death is not None:
            return
        exited = not worker.process.is_alive()  # asked first: what it sent before exiting is in the pipe
        try:
            while worker.conn.poll():
                self._receive(worker.conn.recv())
        except (EOFError, OSError):
            exited = True
        if exited:
            self._mark_dead(worker)

    def _receive(self, message: tuple[Any, ...]) -> None:
        kind, camera, stamp = message[0], message[1], message[2]
        if kind == "frame":
            self._finished.append(Frame(camera, stamp, self._views[camera], message[3]))
        else:
            del self._outstanding[camera]
            self._failures.append(f"camera {camera} {self.cameras[camera].name!r} at {stamp} ns: {message[3]}")

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
    """Ask politely, give a frame's time, then terminate, then kill."""
    for worker in workers:
        try:
            worker.conn.send(("stop",))
        except OSError:
            pass
    deadline = time.monotonic() + STOP_GRACE_S
    for worker in workers:
        worker.process.join(max(0.0, deadline - time.monotonic()))
    for worker in workers:
        if worker.process.is_alive():
            worker.process.terminate()
            worker.process.join(1.0)
        if worker.process.is_alive():
            worker.process.kill()
            worker.process.join()
        worker.conn.close()


def _free(shm: SharedMemory) -> None:
    """Unlink the block; unmap it unless a caller still holds a frame's pixels (then the mapping
    goes when they do)."""
    try:
        shm.close()
    except BufferError:
        log.debug("shared memory %s still viewed by a caller's frame; unmapped when that goes", shm.name)
    try:
        shm.unlink()
    except FileNotFoundError:
        pass


# ---------------------------------------------------------------- the worker process


def _worker_main(
    conn: Connection,
    bodies: tuple[SceneBody, ...],
    jobs: dict[int, tuple[CameraSpec, str]],
    renderer: str,
    light: Light,
) -> None:
    """A render worker: load the scene, report ready, render requests until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the server's to handle; it closes the pool
    os.nice(10)
    _silence_stdio()
    try:
        from simbot.sim.bullet import pb

        scene = _Scene(pb, bodies, jobs, renderer, light)
    except Exception as exc:
        conn.send(("error", "".join(traceback.format_exception_only(type(exc), exc)).strip()))
        return
    conn.send(("ready", scene.renderer, scene.fallback_reason, scene.gl_renderer))
    try:
        _serve(conn, scene)
    finally:
        scene.close()


def _serve(conn: Connection, scene: _Scene) -> None:
    """Render requests in order until told to stop or the server is gone (EOF, broken pipe)."""
    try:
        while (message := conn.recv())[0] == "render":
            _, camera, stamp, pose, states = message
            start = time.perf_counter()
            try:
                scene.render(camera, pose, states)
            except Exception as exc:
                conn.send(("failed", camera, stamp, f"{type(exc).__name__}: {exc}"))
                continue
            conn.send(("frame", camera, stamp, time.perf_counter() - start))
    except (EOFError, OSError):
        return


def _silence_stdio() -> None:
    """C code (PyBullet, the EGL plugin) writes to fds 1 and 2 directly; the server's stdout and
    stderr are for its own output. Python's own tracebacks still reach the real stderr."""
    sys.stdout.flush()
    sys.stderr.flush()
    real_stderr = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    os.close(devnull)
    sys.stderr = open(real_stderr, "w", buffering=1, encoding="utf-8", errors="replace")


@contextmanager
def _captured_output() -> Iterator[list[str]]:
    """What C code prints on fds 1 and 2 inside the block (the list gets it on exit)."""
    text: list[str] = []
    with tempfile.TemporaryFile() as capture:
        saved = [os.dup(1), os.dup(2)]
        os.dup2(capture.fileno(), 1)
        os.dup2(capture.fileno(), 2)
        try:
            yield text
        finally:
            _flush_c_stdio()
            for fd, old in zip((1, 2), saved):
                os.dup2(old, fd)
                os.close(old)
            capture.seek(0)
            text.append(capture.read().decode(errors="replace"))


def _flush_c_stdio() -> None:
    """printf output to a file sits in C's buffer until flushed."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


def _gl_renderer(printed: str) -> str | None:
    match = re.search(r"GL_RENDERER=(.+)", printed) or re.search(r"Renderer = (.+)", printed)
    return match.group(1).strip() if match else None


@dataclass
class _Camera:
    spec: CameraSpec
    projection: Sequence[float]
    shm: SharedMemory
    view: Pixels
    rng: np.random.Generator


@dataclass
class _Scene:
    """The worker's copy of the server's scene, and its cameras."""

    pb: ModuleType
    bodies: tuple[SceneBody, ...]
    jobs: dict[int, tuple[CameraSpec, str]]
    asked: str
    light: Light
    renderer: str = "tiny"
    fallback_reason: str | None = None
    gl_renderer: str | None = None
    ids: dict[str, int] = field(default_factory=dict)
    movable: dict[str, tuple[int, ...]] = field(default_factory=dict)
    cameras: dict[int, _Camera] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.client = self.pb.connect(self.pb.DIRECT)
        if self.asked == "egl":
            self._load_egl()  # before the bodies: the plugin draws only the shapes loaded after it
        self._load_bodies()
        for index, (spec, shm_name) in self.jobs.items():
            self.cameras[index] = self._camera(spec, shm_name)

    def _load_egl(self) -> None:
        spec = importlib.util.find_spec("eglRenderer")
        if spec is None or spec.origin is None:
            self.fallback_reason = "PyBullet's eglRenderer plugin is not installed"
            return
        with _captured_output() as printed:
            plugin = self.pb.loadPlugin(spec.origin, "_eglRendererPlugin", physicsClientId=self.client)
        self.gl_renderer = _gl_renderer(printed[0])
        if plugin < 0:
            last = printed[0].strip().splitlines()[-1:] or ["no message"]
            self.fallback_reason = f"the EGL renderer plugin did not load ({last[0]})"
            return
        self.renderer = "egl"

    def _load_bodies(self) -> None:
        """The same flags as the server, so that base centre-of-mass frames agree."""
        pb = self.pb
        flags = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
        with tempfile.TemporaryDirectory(prefix="simbot-render-") as folder:
            for n, body in enumerate(self.bodies):
                path = os.path.join(folder, f"{n}.urdf")
                with open(path, "w", encoding="utf-8") as file:
                    file.write(body.urdf)
                try:
                    body_id = pb.loadURDF(path, useFixedBase=body.static, flags=flags, physicsClientId=self.client)
                except pb.error as exc:
                    raise RuntimeError(f"body {body.name!r}: {exc}") from None
                # loadURDF places the URDF root link frame; the base pose given is the COM frame's
                pb.resetBasePositionAndOrientation(body_id, *body.base, physicsClientId=self.client)
                self.ids[body.name] = body_id
                self.movable[body.name] = self._one_dof_joints(body_id)

    def _one_dof_joints(self, body_id: int) -> tuple[int, ...]:
        pb = self.pb
        one_dof = (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC)
        count = pb.getNumJoints(body_id, physicsClientId=self.client)
        types = [pb.getJointInfo(body_id, j, physicsClientId=self.client)[2] for j in range(count)]
        return tuple(j for j, kind in enumerate(types) if kind in one_dof)

    def _camera(self, spec: CameraSpec, shm_name: str) -> _Camera:
        shm = SharedMemory(name=shm_name)
        view: Pixels = np.ndarray(spec.shape, dtype=np.uint8, buffer=shm.buf)
        projection = self.pb.computeProjectionMatrixFOV(
            fov=spec.vfov_deg, aspect=spec.width / spec.height, nearVal=spec.near, farVal=spec.far
        )
        return _Camera(spec, projection, shm, view, np.random.default_rng(spec.seed))

    def render(self, camera: int, pose: Transform, states: Mapping[str, BodyState]) -> None:
        """Pose the scene, render, write the pixels into the camera's shared memory."""
        self._apply(states)
        cam = self.cameras[camera]
        spec = cam.spec
        image = self.pb.getCameraImage(
            spec.width,
            spec.height,
            self._view_matrix(pose),
            cam.projection,
            renderer=self.pb.ER_BULLET_HARDWARE_OPENGL if self.renderer == "egl" else self.pb.ER_TINY_RENDERER,
            flags=self.pb.ER_NO_SEGMENTATION_MASK,
            shadow=0,
            lightDirection=[-v for v in self.light.direction],
            lightColor=list(self.light.color),
            lightAmbientCoeff=self.light.ambient,
            lightDiffuseCoeff=self.light.diffuse,
            lightSpecularCoeff=self.light.specular,
            physicsClientId=self.client,
        )
        rgb = np.asarray(image[2], dtype=np.uint8).reshape(spec.height, spec.width, 4)[:, :, :3]
        pixels = _luminance(rgb) if spec.channels == 1 else rgb
        if spec.noise_stddev > 0.0:
            pixels = _noisy(pixels, spec.noise_stddev, cam.rng)
        cam.view[...] = pixels

    def _apply(self, states: Mapping[str, BodyState]) -> None:
        pb, client = self.pb, self.client
        for name, state in states.items():
            body_id = self.ids[name]
            pb.resetBasePositionAndOrientation(body_id, *state.base, physicsClientId=client)
            movable = self.movable[name]
            if movable and len(state.joints) <= movable[-1]:
                raise ValueError(f"body {name!r}: {len(state.joints)} joint positions, joint {movable[-1]} moves")
            for j in movable:
                pb.resetJointState(body_id, j, state.joints[j], physicsClientId=client)

    def _view_matrix(self, pose: Transform) -> Sequence[float]:
        """Camera looks along its +x with z up (SDF): forward = R·x, up = R·z."""
        position, quat = pose
        rotation = np.asarray(self.pb.getMatrixFromQuaternion(quat)).reshape(3, 3)
        target = np.asarray(position) + rotation[:, 0]
        return self.pb.computeViewMatrix(list(position), target.tolist(), rotation[:, 2].tolist())

    def close(self) -> None:
        for cam in self.cameras.values():
            del cam.view  # the view first: a mapping with live views cannot be closed
            cam.shm.close()
        self.cameras.clear()
        self.pb.disconnect(physicsClientId=self.client)


def _luminance(rgb: Pixels) -> Pixels:
    weights = np.asarray(LUMA, dtype=np.float32)
    out: Pixels = np.rint(rgb.astype(np.float32) @ weights).astype(np.uint8)
    return out


def _noisy(pixels: Pixels, stddev: float, rng: np.random.Generator) -> Pixels:
    noise = rng.standard_normal(pixels.shape, dtype=np.float32) * np.float32(stddev * 255.0)
    out: Pixels = np.clip(np.rint(pixels + noise), 0, 255).astype(np.uint8)
    return out
