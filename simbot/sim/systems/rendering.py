"""Rendering: the one system that renders every camera-type sensor of the world.

Camera sensors (`camera`, `depth_camera`, `rgbd_camera`, and any sensor module that follows the
`RenderedSensor` contract) register here when they are built; this system owns the render pool
(simbot/sim/render/), started in the background when the first image is wanted, and decides at
each step which cameras render. The sensors themselves only say what they render (a
`CameraSpec`), whether anyone wants it, and turn a finished `Frame` into messages. As Gazebo's
Sensors system gives all sensors one render engine, one owner here keeps the cameras from
coordinating among themselves.

Scheduling, after each physics step:
- A camera whose tick comes and whose outputs someone subscribes to waits for a frame. When only
  its camera_info is subscribed, camera_info goes out at the tick.
- Real time and fast mode: the waiting cameras render as one set, from one snapshot of the
  moving bodies, at the first step when every frame of the previous set is out (a set shares one
  stamp, as Gazebo's cameras do, and a stitcher pairing six images by stamp finds them
  together). A tick that finds its camera still waiting is skipped and counted (`skipped` in
  world state), so rendering never slows the physics.
- Lockstep: every frame is rendered at its exact sim time, and the step that took it waits until
  the frames of all cameras due then are published, so after `multi_step` every frame up to
  that time is out.

Models created and removed at run time (world control `create`, `remove`): the pool loads the
world as it is when it starts. What changes after that snapshot (bodies added or removed, in
order, and cameras added) is sent to the pool before the next set of requests, and at once when
the pool runs; a worker reads its messages in order, so every camera of a set draws the same
scene, and the first set requested after a create draws the created bodies (lockstep stays exact
and deterministic: the same calls send the same messages in the same order). A camera of a
created model takes the next index and renders like the others; a removed model's bodies leave
the scenes, and its cameras stop (their slots stay empty, so the others keep their places).
When the last camera leaves, the pool closes; a camera created later starts a fresh one.

A render worker that dies, or a pool that does not start, stops the cameras (an error in the log
and in each camera's world state), never the simulation.
"""

from __future__ import annotations

import logging
import threading
from typing import Protocol

from simbot.description.model import World
from simbot.description.poses import Pose
from simbot.sim.physics import Physics
from simbot.sim.render import BodyState, CameraSpec, Frame, Light, RenderPool, SceneBody, plan_pool
from simbot.sim.system import SensorSettings, UpdateInfo

log = logging.getLogger(__name__)

LOCKSTEP_TIMEOUT_S = 120.0
"""How long lockstep waits for one frame before it gives the cameras up as broken."""


class RenderedSensor(Protocol):
    """What a camera-type sensor gives the rendering system."""

    spec: CameraSpec
    where: tuple[str, str, Pose]
    """(model, link, pose in the link): where the camera is, looking along its +x with z up."""
    skipped: int

    def due(self, info: UpdateInfo) -> bool: ...

    def wanted(self) -> bool:
        """Someone subscribes to an output that needs rendering."""
        ...

    def publish_info(self, stamp_ns: int) -> None:
        """camera_info alone, for a tick with no frame to render."""
        ...

    def publish(self, frame: Frame) -> None:
        """The frame's messages and its camera_info, under the frame's stamp."""
        ...


def world_light(world: World) -> Light:
    """The world's first directional light (the sun) drives the renderers' one light."""
    sun = next((light for light in world.lights if light.type == "directional"), None)
    return Light(direction=sun.direction) if sun else Light()


class Rendering:
    """Schedules the cameras and owns their render pool; see the module docstring."""

    name = "rendering"

    def __init__(self, physics: Physics, settings: SensorSettings, light: Light) -> None:
        self.physics = physics
        self.settings = settings
        self.light = light
        self.cameras: list[RenderedSensor] = []
        self.pool: RenderPool | None = None
        self.failure: str | None = None
        self._starting: threading.Thread | None = None
        self._waiting: set[int] = set()
        self._gone: set[int] = set()
        """Cameras of removed models, by index."""
        self._changes: list[SceneBody | str] = []
        """Since the pool's snapshot of the world, not yet sent to it: bodies added (a SceneBody) and removed (a name)."""

    def add(self, camera: RenderedSensor) -> int:
        """Register a camera; its index in the pool (a running pool takes it at once)."""
        self.cameras.append(camera)
        self._sync()
        return len(self.cameras) - 1

    def add_model(self, bodies: list[str]) -> None:
        """Bodies new in the physics enter the render scenes; call it once the physics holds them."""
        if self._following:
            self._changes += [self._scene_body(body) for body in bodies]
            self._sync()

    def remove_model(self, name: str, bodies: list[str]) -> None:
        """The model `name` (its `bodies`) leaves the world: its cameras stop, its bodies leave the
        scenes. Call it before the physics removes them."""
        for index, camera in enumerate(self.cameras):
            if camera.where[0] in bodies:
                self._gone.add(index)
                self._waiting.discard(index)
        if self._following:
            self._changes += bodies
        if self.pool is not None and len(self._gone) == len(self.cameras):
            log.info("the last camera left with model %s: the render workers stop", name)
            self._stop_pool()
        else:
            self._sync()

    @property
    def _following(self) -> bool:
        """A pool has taken (or is taking) its snapshot of the world and works on: it must follow the changes."""
        return self._starting is not None and self.failure is None

    def _stop_pool(self) -> None:
        """No camera is left: the pool closes, and the next camera watched starts a fresh one."""
        self.close()
        self.cameras, self._gone, self._changes, self._starting = [], set(), [], None

    def _sync(self) -> None:
        """Sends a running pool what changed since its snapshot of the world, in order."""
        if self.pool is None:
            return
        changes, self._changes = self._changes, []
        try:
            for change in changes:
                if isinstance(change, SceneBody):
                    self.pool.add_body(change)
                else:
                    self.pool.remove_body(change)
            for camera in self.cameras[len(self.pool.cameras) :]:
                self.pool.add_camera(camera.spec)
        except RuntimeError as exc:
            self.fail(str(exc))

    def _scene_body(self, name: str) -> SceneBody:
        """A body as the physics loaded it, where it is now."""
        body = self.physics.bodies[name]
        return SceneBody(name, body.urdf, body.model.static, self.physics.body_state(name)[0])

    # --- the update

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = info.sim_time_ns
        for index, camera in enumerate(self.cameras):
            if index in self._gone or not camera.due(info):
                continue
            if camera.wanted() and self.failure is None:
                camera.skipped += index in self._waiting  # real time: the physics never waits for a frame
                self._waiting.add(index)
            else:
                camera.publish_info(now_ns)
        if self._waiting and self._ready() and self._idle():
            self._request(now_ns)
        self._deliver()

    def _ready(self) -> bool:
        """Whether the pool takes requests; starts it (in the background) on first call."""
        if self.pool is not None:
            return True
        if self.failure is not None:
            return False
        if self._starting is None:  # the snapshot of the world: what changes after it goes to `_changes`
            bodies = [self._scene_body(name) for name in self.physics.bodies]
            specs = [camera.spec for camera in self.cameras]
            self._starting = threading.Thread(
                target=self._start, args=(bodies, specs), name="render-pool-start", daemon=True
            )
            self._starting.start()
        if self.settings.lockstep:
            self._starting.join()
        return self.pool is not None

    def _start(self, bodies: list[SceneBody], specs: list[CameraSpec]) -> None:
        """Runs in a thread (PyBullet is not touched here): spawning workers and loading the scene
        takes seconds the loop must not wait."""
        plan = plan_pool(len(specs), self.settings.render_workers)
        try:
            pool = RenderPool(
                bodies, specs, plan.workers, self.settings.renderer, self.light, gl_threads=plan.gl_threads
            )
        except (OSError, RuntimeError, ValueError) as exc:
            self.failure = f"the camera render workers did not start: {exc}"
            log.error("%s; no images will be published", self.failure)
            return
        if pool.fallback_reason:
            log.warning("cameras render with TinyRenderer: %s", pool.fallback_reason)
        self.pool = pool

    def _idle(self) -> bool:
        """No frame of any camera outstanding (lockstep never has one here)."""
        return self.pool is not None and not any(self.pool.busy(i) for i in range(len(self.cameras)))

    def _request(self, now_ns: int) -> None:
        """Every waiting camera renders from one snapshot of the moving bodies, in the scenes as the
        world has them now."""
        self._sync()
        if self.pool is None:  # the pool broke taking the changes
            return
        states = {name: BodyState(*self.physics.body_state(name)) for name in self.physics.moving_bodies()}
        waiting, self._waiting = sorted(self._waiting), set()
        try:
            for index in waiting:
                self.pool.request(index, now_ns, self.physics.frame_pose(*self.cameras[index].where), states)
        except RuntimeError as exc:
            self.fail(str(exc))

    def _deliver(self) -> None:
        """Publishes the frames that are done; in lockstep, first waits for every outstanding one."""
        if self.pool is None:
            return
        try:
            waits = [i for i in range(len(self.cameras)) if i not in self._gone] if self.settings.lockstep else [None]
            frames = [
                frame for camera in waits for frame in self.pool.collect(wait_for=camera, timeout=LOCKSTEP_TIMEOUT_S)
            ]
        except (RuntimeError, TimeoutError) as exc:
            self.fail(str(exc))
            return
        for frame in frames:
            if frame.camera not in self._gone:
                self.cameras[frame.camera].publish(frame)

    def fail(self, reason: str) -> None:
        """A broken pool stops the cameras, not the simulation."""
        log.error("cameras stopped: %s", reason)
        self.failure = reason
        self._waiting.clear()
        self.close()

    @property
    def renderer(self) -> str | None:
        return None if self.pool is None else self.pool.renderer_used

    def reset(self, info: UpdateInfo) -> None:
        """The world was reset: waiting ticks belong to the old timeline."""
        self._waiting.clear()

    def close(self) -> None:
        if self._starting is not None:
            self._starting.join()
        if self.pool is not None:
            self.pool.close()
            self.pool = None
