"""Rendering: the one system that renders every camera-type sensor of the world.

A world system (built in, no `<plugin>`). Camera sensors (`camera`, `depth_camera`,
`rgbd_camera`, and any sensor module that follows the `RenderedSensor` contract of
simbot/sim/kit/rendered_sensor.py) are found among the systems of each model that enters the world
(`model_added`); this system owns the render pool
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

Models created and removed at run time (world control `create`, `remove`), and a seeded reset
applied in place (simbot.sim.loop.world_edit: models restyled, moved, replaced, added, removed;
the lighting changed, `world_changed`): the pool loads the world as it is when it starts, and runs
on. What changes after that snapshot (bodies added, removed, replaced; the lighting; cameras
added, a camera's noise changed) is sent to the pool as one edit before the next set of
requests, the bodies in the order a world loaded afresh holds them (`_order`: the workers batch
in it, so an edited world draws as a fresh one does); a worker reads its messages in order, so
every camera of a set draws the same scene, and the first set requested after a change draws it
(lockstep stays exact and deterministic: the same calls send the same messages in the same
order). A camera of a created model takes the next index and renders like the others; a removed
model's bodies leave the scenes, and its cameras stop (their slots stay empty, so the others keep
their places); a camera whose model was restyled in place keeps its index. When the last camera
has left, the pool closes; a camera created later starts a fresh one. On every reset the frames
still being drawn are dropped and each camera's noise starts again from its seed.

The images leave from the workers (simbot/sim/render/publishing.py): each joins the bus as a
client of the server and publishes the frames of the cameras that give it a publication, on the
keys the camera found subscribed when the frame was asked for (`audience`: the server's view, so
what a lockstep client receives never depends on when a worker's session heard of it); the
frames come back here only to be counted (and saved, and boxed). In lockstep the workers wait at
the server's barrier queryable (`BARRIER`) until their samples are routed, so a step's images
arrive before its clock, as when the server published them. Where no other process can join the
node (`Node.hosts_helpers`: a learning environment's world, simbot.bus.local), the workers get no
bus and the cameras put their frames from shared memory here, in the step that asked for them.

A render worker that dies, or a pool that does not start, stops the cameras (an error in the log
and in each camera's world state), never the simulation.
"""

from __future__ import annotations

import logging
import sys
import threading
from collections.abc import Iterable, Sequence

from simbot.bus.options import helper_options
from simbot.description.model import SdfLight, World
from simbot.sim.kit.rendered_sensor import Annotating, RenderedSensor, RenderStatus
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo
from simbot.sim.render import (
    Annotation,
    BodyState,
    Frame,
    Light,
    LightSource,
    RenderPool,
    SceneBody,
    plan_pool,
    starter,
)
from simbot.sim.render.label_bits import MAX_INSTANCE
from simbot.sim.render.publishing import Bus
from simbot.transform import matmul

log = logging.getLogger(__name__)

LOCKSTEP_TIMEOUT_S = 120.0
"""How long lockstep waits for one frame before it gives the cameras up as broken."""
BARRIER = "simbot/render_barrier"
"""The queryable a lockstep worker asks after its puts (in the server's namespace)."""


def world_light(world: World) -> Light:
    """The world's lighting as the renderers shade it: its `<light>`s in the world frame, and its
    `<scene>` ambient, background and shadows. Lights of models are not drawn."""
    scene = world.scene
    return Light(
        sources=tuple(_light_source(light) for light in world.lights if light.type in ("directional", "point", "spot")),
        ambient=scene.ambient[:3],
        background=scene.background[:3],
        shadows=scene.shadows,
        ambient_temperature=world.atmosphere.temperature,
        temperature_gradient=world.atmosphere.temperature_gradient,
    )


def _light_source(light: SdfLight) -> LightSource:
    """An SDF light in the world frame: its pose places it and turns its direction."""
    placed = light.pose.matrix()
    return LightSource(
        type=light.type,
        diffuse=_scaled(light.diffuse, light.intensity),
        specular=_scaled(light.specular, light.intensity),
        position=tuple(float(v) for v in placed[:3, 3]),  # type: ignore[arg-type]
        direction=tuple(float(v) for v in matmul(placed[:3, :3], light.direction)),  # type: ignore[arg-type]
        range=light.attenuation_range,
        attenuation=(light.constant, light.linear, light.quadratic),
        spot=(light.inner_angle, light.outer_angle, light.falloff),
        cast_shadows=light.cast_shadows,
    )


def _scaled(rgba: tuple[float, ...], intensity: float) -> tuple[float, float, float]:
    return (rgba[0] * intensity, rgba[1] * intensity, rgba[2] * intensity)


class Rendering:
    """Schedules the cameras and owns their render pool; see the module docstring.

    Command-line parameters (`RunOptions.overrides`): `rendering.renderer` (auto | gl | tiny,
    default auto), `rendering.workers` (render processes) and `rendering.threads` (llvmpipe threads
    of each; defaults: `plan_pool`'s measured policy)."""

    name = "Rendering"

    def __init__(self, ctx: SystemContext) -> None:
        self.physics = ctx.physics
        self.lockstep = ctx.options.lockstep
        self.renderer_asked: str = ctx.override("rendering.renderer") or "auto"
        self.workers: int | None = ctx.override("rendering.workers")
        self.threads: int | None = ctx.override("rendering.threads")
        self.world = ctx.world
        self.light = world_light(ctx.world)
        self._relit = False
        """The lighting changed since the pool last heard of it."""
        self._respec = False
        """A reset came: every noisy camera's spec goes to the pool again, its noise to start again from its seed."""
        node = ctx.bus.node
        if self.lockstep and node.hosts_helpers:
            node.answering(BARRIER)
        barrier = node.key("/" + BARRIER) if self.lockstep else None
        self.bus = Bus(helper_options(node.options), barrier) if node.hosts_helpers else None
        """Where the render workers publish; None where they cannot reach the bus (a world in a
        learning environment's process): the cameras publish their frames themselves."""
        self.status = RenderStatus()
        self.cameras: list[RenderedSensor] = []
        self.pool: RenderPool | None = None
        self._starting: threading.Thread | None = None
        self._waiting: set[int] = set()
        self._gone: set[int] = set()
        """Cameras of removed models, by index."""
        self._changes: list[SceneBody | str] = []
        """Since the pool's snapshot of the world, not yet sent to it, in order: bodies added (a
        SceneBody) and removed (a name); a name removed and added again is the body replaced."""
        self._annotations: dict[str, tuple[Annotation, ...]] = {}
        """Each body's labels and temperatures (`Annotating` systems of its model), in the order they came."""
        self._instances: dict[str, int] = {}
        """Each body's instance number for segmentation, counted up as bodies come (1..65535, then again)."""
        self._counted = 0
        self._next_due_ns = 0
        """Sim time of the next tick of any camera watched: no step before it looks at the cameras."""
        self._watching = node.watching
        self._seen: int | None = None
        """The node's `Watching.generation` when the cameras watched were last looked for."""
        self._listening: list[int] = []
        """The cameras someone subscribes to (or that save their frames), by index, as of `_seen`."""
        self._now_ns = 0
        """Sim time of the last step seen (0 before the first and after a reset)."""
        self._came_ns: dict[int, int] = {}
        """Each camera's sim time of the last step before it came into the world (0: there from the start)."""

    def model_added(self, event: ModelEvent) -> None:
        """Its bodies enter the render scenes, then its cameras take the next indices (a running pool
        takes them at once)."""
        self._annotate(event)
        if self._following:
            self._changes += [self._scene_body(body) for body in event.bodies]
        for camera in event.systems:
            if isinstance(camera, RenderedSensor):
                self._take(camera)

    def _take(self, camera: RenderedSensor) -> None:
        """A camera to render: one back with its model (the model's description edited in place,
        its systems kept) keeps its index; a new one takes the next."""
        if not self.cameras:
            starter.warm_up()  # the fork server's imports overlap the rest of the world's loading
        camera.status = self.status
        back = next((i for i in self._gone if self.cameras[i] is camera), None)
        if back is not None:
            self._gone.discard(back)
        else:
            self.cameras.append(camera)
        self._came_ns[back if back is not None else len(self.cameras) - 1] = self._now_ns
        self._next_due_ns, self._seen = 0, None

    def model_removed(self, event: ModelEvent) -> None:
        """Its cameras stop, its bodies leave the scenes (before the physics removes them)."""
        bodies = event.bodies
        for body in bodies:
            self._annotations.pop(body, None)
            self._instances.pop(body, None)
        for index, camera in enumerate(self.cameras):
            if camera.where[0] in bodies:
                self._gone.add(index)
                self._waiting.discard(index)
        self._seen = None
        if self._following:
            self._changes += bodies
        if self.pool is not None and len(self._gone) == len(self.cameras):
            log.info("the last camera left with model %s: the render workers stop", event.name)
            self._stop_pool()

    def world_changed(self, world: World) -> None:
        """The world's description was edited in place (a seeded reset): its lighting goes to the
        workers with the next set of frames, and its models' order is the scene's."""
        self.world = world
        light = world_light(world)
        if light != self.light:
            self.light, self._relit = light, True

    @property
    def _following(self) -> bool:
        """A pool has taken (or is taking) its snapshot of the world and works on: it must follow the changes."""
        return self._starting is not None and self.status.failure is None

    def _stop_pool(self) -> None:
        """No camera is left: the pool closes, and the next camera watched starts a fresh one."""
        self.close()
        self.cameras, self._gone, self._changes, self._starting = [], set(), [], None
        self._seen, self._listening, self._came_ns = None, [], {}

    def _sync(self) -> None:
        """Sends a running pool what changed since its snapshot of the world, as one edit: the
        bodies out and in, the lighting, the scene's order; then the cameras added and changed."""
        if self.pool is None:
            return
        pool, changes, self._changes = self.pool, self._changes, []
        removed, added = _net(changes, pool.body_names)
        try:
            if removed or added or self._relit:
                kept = (pool.body_names - set(removed)) | set(added)
                pool.edit(removed, added.values(), self.light if self._relit else None, self._order(kept))
            self._relit = False
            for camera in self.cameras[len(pool.cameras) :]:
                pool.add_camera(camera.spec, camera.publication)
            for index, camera in enumerate(self.cameras):
                noisy = self._respec and camera.spec.noise_stddev > 0.0  # its noise starts again from its seed
                if index not in self._gone and (noisy or camera.spec != pool.cameras[index]):
                    pool.update_camera(index, camera.spec)
            self._respec = False
        except RuntimeError as exc:
            self.fail(str(exc))

    def _annotate(self, event: ModelEvent) -> None:
        """The model's labels and temperatures, and an instance number for each of its bodies."""
        annotations = tuple(s.annotation for s in event.systems if isinstance(s, Annotating))
        for body in event.bodies:
            self._annotations[body] = annotations
            self._instances[body] = self._counted % MAX_INSTANCE + 1
            self._counted += 1

    def _order(self, bodies: Iterable[str]) -> list[str]:
        """The bodies in the order a world loaded afresh holds them: the world's models as its
        description lists them, then the rest (the robots, models created since) as the physics
        took them. The workers batch in it, so an edited world draws as a fresh one."""
        models = {model.name: i for i, model in enumerate(self.world.models)}
        loaded = {name: i for i, name in enumerate(self.physics.body_names())}
        return sorted(bodies, key=lambda body: (models.get(body.split("::")[0], len(models)), loaded.get(body, 0)))

    def _scene_body(self, name: str) -> SceneBody:
        """A body as the physics loaded it, where it is now, with its annotations."""
        return scene_body(self.physics, name, self._annotations.get(name, ()), self._instances.get(name, 0))

    # --- the update

    def post_update(self, info: UpdateInfo) -> None:
        now_ns = self._now_ns = info.sim_time_ns
        if now_ns >= self._next_due_ns or self._watching.generation != self._seen:
            self._tick(info)
        if self._waiting and self._ready() and self._idle():
            self._request(now_ns)
        self._deliver()

    def _tick(self, info: UpdateInfo) -> None:
        """Each camera watched and due waits for a frame, or (only its camera_info watched) sends
        camera_info alone; then the next tick of any: the steps between cost nothing here, however
        many cameras there are, and cameras no one watches cost nothing at all."""
        next_due_ns = sys.maxsize
        for index in self._listened(info):
            camera = self.cameras[index]
            if camera.due(info):
                if camera.wanted() and self.status.failure is None:
                    camera.skipped += index in self._waiting  # real time: the physics never waits for a frame
                    self._waiting.add(index)
                else:
                    camera.publish_info(info.sim_time_ns)
            next_due_ns = min(next_due_ns, camera.next_due_ns)
        self._next_due_ns = next_due_ns

    def _listened(self, info: UpdateInfo) -> list[int]:
        """The cameras someone subscribes to (any output or camera_info) or that save their frames,
        looked for again only when who subscribes to the node's publishers changed (a fleet's six
        thousand cameras, none watched, cost one comparison a step); one that comes back into view
        catches up with its rate (`resume`), as if it had been asked at every step."""
        if self._watching.generation != self._seen:
            self._seen = self._watching.generation  # read first: a change while looking comes again
            before = set(self._listening)
            self._listening = [
                index
                for index, camera in enumerate(self.cameras)
                if index not in self._gone and (camera.wanted() or camera.audience())
            ]
            for index in self._listening:
                if index not in before:
                    self.cameras[index].resume(info, self._came_ns.get(index, 0))
        return self._listening

    def _ready(self) -> bool:
        """Whether the pool takes requests; starts it (in the background) on first call."""
        if self.pool is not None:
            return True
        if self.status.failure is not None:
            return False
        if self._starting is None:  # the snapshot of the world: what changes after it goes to `_changes`
            bodies = [self._scene_body(name) for name in self._order(self.physics.body_names())]
            cameras = list(self.cameras)
            self._starting = threading.Thread(
                target=self._start, args=(bodies, cameras), name="render-pool-start", daemon=True
            )
            self._starting.start()
        if self.lockstep:
            self._starting.join()
        return self.pool is not None

    def _start(self, bodies: list[SceneBody], cameras: list[RenderedSensor]) -> None:
        """Runs in a thread (PyBullet is not touched here): spawning workers and loading the scene
        takes seconds the loop must not wait."""
        plan = plan_pool(len(cameras), self.workers, asked_threads=self.threads)
        try:
            pool = RenderPool(
                bodies,
                [camera.spec for camera in cameras],
                plan.workers,
                self.renderer_asked,
                self.light,
                gl_threads=plan.gl_threads,
                bus=self.bus,
                publications=[camera.publication for camera in cameras],
            )
        except (OSError, RuntimeError, ValueError) as exc:
            self.status.failure = f"the camera render workers did not start: {exc}"
            log.error("%s; no images will be published", self.status.failure)
            return
        if pool.fallback_reason:
            log.warning("cameras render with TinyRenderer: %s", pool.fallback_reason)
        self.pool = pool
        self.status.renderer = pool.renderer_used

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
                camera = self.cameras[index]
                self.pool.request(index, now_ns, self.physics.frame_pose(*camera.where), states, camera.audience())
        except RuntimeError as exc:
            self.fail(str(exc))

    def _deliver(self) -> None:
        """Publishes the frames that are done; in lockstep, first waits for every outstanding one.
        A frame dropped (its worker died during an edit) counts as skipped."""
        frames = self._collect(self.lockstep)
        if self.pool is None:
            return
        for frame in frames:
            if frame.camera not in self._gone:
                self.cameras[frame.camera].publish(frame)
        for index in self.pool.dropped():
            self.cameras[index].skipped += 1

    def _collect(self, wait: bool) -> list[Frame]:
        """The frames done; waiting first for every outstanding one where asked. A broken pool fails."""
        if self.pool is None:
            return []
        try:
            waits = [i for i in range(len(self.cameras)) if i not in self._gone] if wait else [None]
            return [frame for i in waits for frame in self.pool.collect(wait_for=i, timeout=LOCKSTEP_TIMEOUT_S)]
        except (RuntimeError, TimeoutError) as exc:
            self.fail(str(exc))
            return []

    def fail(self, reason: str) -> None:
        """A broken pool stops the cameras, not the simulation."""
        log.error("cameras stopped: %s", reason)
        self.status.failure = reason
        self._waiting.clear()
        self.close()

    def reset(self, info: UpdateInfo) -> None:
        """The world was reset: waiting ticks belong to the old timeline, and so do frames still
        being drawn: they are waited for and dropped (a worker that publishes its frames has put
        them out before the reset is done: none of the old world comes after it); each camera's
        noise starts again from its seed."""
        self._waiting.clear()
        self._next_due_ns, self._now_ns = 0, 0
        self._came_ns = dict.fromkeys(self._came_ns, 0)
        self._collect(wait=True)
        self._respec = True

    def close(self) -> None:
        if self._starting is not None:
            self._starting.join()
        if self.pool is not None:
            self.pool.close()
            self.pool = None
            self.status.renderer = None


def _net(changes: Sequence[SceneBody | str], held: frozenset[str]) -> tuple[list[str], dict[str, SceneBody]]:
    """Changes in order as one edit of a scene that holds `held`: the names it drops (a body added
    and removed meanwhile never reaches it), and the bodies it takes in (a name in both: replaced)."""
    removed: list[str] = []
    added: dict[str, SceneBody] = {}
    for change in changes:
        if isinstance(change, SceneBody):
            added[change.name] = change
            continue
        added.pop(change, None)
        if change in held and change not in removed:
            removed.append(change)
    return removed, added
