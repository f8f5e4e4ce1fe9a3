"""Camera (SDF `camera`): images rendered in worker processes, stamped with the sim time they show.

Each camera is a system; all cameras of a world share one `CameraRig`, which owns the render
pool (see simbot/sim/rendering.py): worker processes holding a copy of the scene. At each of its
ticks a camera that someone subscribes to takes the camera's world pose and the state of every
moving body (one snapshot per tick, shared by the cameras due then) and hands them to the pool.
The image comes back later and is published stamped with the snapshot's sim time.

- Real time and fast mode: a camera whose tick comes while frames are still rendering waits
  (one frame at most: a tick that finds it still waiting is skipped, and counted in world
  state's `skipped`), so rendering never slows the physics. The waiting cameras render as one
  set at the first step when every frame of the previous set is out: a set shares one stamp,
  as Gazebo's cameras do, and a stitcher pairing the six images by stamp finds them together.
  (Letting each camera render as soon as it alone is free would drift the six apart by a frame
  time each; holding a set for the next tick would leave the workers idle for half a tick.)
- Lockstep: every frame is rendered at its exact sim time, and the step that took it waits
  until the frames of all cameras due then are published (the cameras render in parallel when
  there are several workers), so after `multi_step` every frame up to that time is out.
- Nobody subscribed to the image: nothing is rendered, and no worker is started until someone
  subscribes. `camera_info` is published at the camera's rate whenever someone listens to it.

Images are stamped in the camera's optical frame (z forward, x right, y down; tf_static places
it), as ROS expects of camera data; `camera_info` holds the true pinhole intrinsics:
fx = fy = (w/2)/tan(hfov/2), principal point at the image centre ((w−1)/2, (h−1)/2 in ROS's
pixel-centre coordinates, where PyBullet's symmetric frustum puts it).
"""

from __future__ import annotations

import logging
import os
import threading
from dataclasses import dataclass, field
from typing import Any

from simbot.bus import Publisher, messages
from simbot.bus.frames import optical_frame
from simbot.description.model import World
from simbot.sim.physics import Physics
from simbot.sim.rendering import BodyState, CameraSpec, Frame, Light, RenderPool, SceneBody
from simbot.sim.system import (
    Sampled,
    SensorSettings,
    SystemConfigError,
    SystemContext,
    applied_noise,
    sensor_frame,
    sensor_rate,
    sensor_topic,
)

log = logging.getLogger(__name__)

CHANNELS = {"R8G8B8": 3, "RGB_INT8": 3, "L8": 1, "L_INT8": 1}
"""SDF image formats simbot renders, by the number of uint8 channels (rgb8, mono8)."""
DEFAULT_RATE_HZ = 30.0
LOCKSTEP_TIMEOUT_S = 120.0
"""How long lockstep waits for one frame before it gives the camera up as broken."""
RIG = "camera_rig"


def worker_count(cameras: int, asked: int | None = None) -> int:
    """Render workers: as asked, else those that fit, every core but one (the physics keeps it); at most one per camera."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(cameras, asked or cores - 1))


def _light(world: World) -> Light:
    """The world's first directional light (the sun) drives TinyRenderer's one light."""
    sun = next((light for light in world.lights if light.type == "directional"), None)
    return Light(direction=sun.direction) if sun else Light()


@dataclass
class CameraRig:
    """The cameras of one world and the pool that renders them, started when first needed."""

    physics: Physics
    settings: SensorSettings
    light: Light
    cameras: list[Camera] = field(default_factory=list)
    pool: RenderPool | None = None
    failure: str | None = None
    _starting: threading.Thread | None = None
    _snapshot: tuple[int, dict[str, BodyState]] | None = None
    _tick: tuple[int, bool] | None = None

    def add(self, camera: Camera) -> int:
        self.cameras.append(camera)
        return len(self.cameras) - 1

    def ready(self) -> bool:
        """Whether the pool can take requests; starts it (in the background) on first call."""
        if self.pool is not None:
            return True
        if self.failure is not None:
            return False
        if self._starting is None:
            bodies = [SceneBody(name, body.urdf, body.model.static, self.physics.body_state(name)[0]) for name, body in self.physics.bodies.items()]
            self._starting = threading.Thread(target=self._start, args=(bodies,), name="render-pool-start", daemon=True)
            self._starting.start()
        if self.settings.lockstep:
            self._starting.join()
        return self.pool is not None

    def _start(self, bodies: list[SceneBody]) -> None:
        """Runs in a thread (PyBullet is not touched here): spawning workers and loading the scene
        takes seconds the loop must not wait."""
        specs = [camera.spec for camera in self.cameras]
        try:
            pool = RenderPool(bodies, specs, worker_count(len(specs), self.settings.render_workers), self.settings.renderer, self.light)
        except (OSError, RuntimeError, ValueError) as exc:
            self.failure = f"the camera render workers did not start: {exc}"
            log.error("%s; no images will be published", self.failure)
            return
        if pool.fallback_reason:
            log.warning("--renderer %s is not available (%s); rendering with TinyRenderer", self.settings.renderer, pool.fallback_reason)
        self.pool = pool

    def states(self, now_ns: int) -> dict[str, BodyState]:
        """Every moving body's state now; taken once per tick for all cameras due then."""
        if self._snapshot is None or self._snapshot[0] != now_ns:
            states = {name: BodyState(*self.physics.body_state(name)) for name in self.physics.moving_bodies()}
            self._snapshot = (now_ns, states)
        return self._snapshot[1]

    def accepting(self, now_ns: int) -> bool:
        """Whether frames may be requested at `now_ns`: decided once per step, true when no frame of
        any camera is outstanding (lockstep never has one here)."""
        if self._tick is None or self._tick[0] != now_ns:
            idle = self.pool is not None and not any(self.pool.busy(camera.index) for camera in self.cameras)
            self._tick = (now_ns, idle)
        return self._tick[1]

    def forget(self) -> None:
        """The world was reset: sim time starts again, so a snapshot's or a tick's time no longer names it."""
        self._snapshot = None
        self._tick = None

    def deliver(self) -> None:
        """Publishes the frames that are done; in lockstep, first waits for every outstanding one."""
        if self.pool is None:
            return
        try:
            waits = range(len(self.cameras)) if self.settings.lockstep else [None]
            frames = [frame for camera in waits for frame in self.pool.collect(wait_for=camera, timeout=LOCKSTEP_TIMEOUT_S)]
        except (RuntimeError, TimeoutError) as exc:
            self.fail(str(exc))
            return
        for frame in frames:
            self.cameras[frame.camera].publish(frame)

    def fail(self, reason: str) -> None:
        """A broken pool stops the cameras, not the simulation."""
        log.error("cameras stopped: %s", reason)
        self.failure = reason
        self.close()

    def close(self) -> None:
        if self._starting is not None:
            self._starting.join()
        if self.pool is not None:
            self.pool.close()
            self.pool = None


class Camera(Sampled):
    """sensor_msgs/Image on `<topic>` and CameraInfo on `<topic>/camera_info`, at the camera's rate."""

    def __init__(self, ctx: SystemContext) -> None:
        model, link, sensor = ctx.require_sensor()
        if sensor.camera is None:
            raise SystemConfigError(f"sensor {sensor.name}: type 'camera' needs a <camera> element")
        spec = sensor.camera
        channels = CHANNELS.get(spec.format)
        if channels is None:
            raise SystemConfigError(f"sensor {sensor.name}: <format> {spec.format!r} is not rendered; use one of {', '.join(CHANNELS)}")
        width, height = ctx.settings.camera_size or (spec.width, spec.height)
        try:
            self.spec = CameraSpec(
                sensor.name, width, height, spec.horizontal_fov, spec.near, spec.far, channels, applied_noise(spec.noise).stddev, int(ctx.rng.integers(2**31))
            )
        except ValueError as exc:
            raise SystemConfigError(f"sensor {sensor.name}: {exc}") from None
        super().__init__(sensor.name, ctx.settings.camera_rate or sensor_rate(sensor, DEFAULT_RATE_HZ))
        self._physics = ctx.physics
        self._where = (model, link.name, sensor.pose)
        self._frame = optical_frame(sensor_frame(sensor))
        topic = sensor_topic(sensor)
        self._image: Publisher = ctx.bus.publisher(topic, messages.Image)
        self._info: Publisher = ctx.bus.publisher(f"{topic}/camera_info", messages.CameraInfo)
        self.rig: CameraRig = ctx.shared.setdefault(RIG, CameraRig(ctx.physics, ctx.settings, _light(ctx.world)))
        self.index = self.rig.add(self)
        self.skipped = 0
        self._waiting = False
        """A tick came while the rig was busy: render at the first step it accepts."""

    def post_update(self, now_ns: int) -> None:
        if self.due(now_ns):
            if self._info.has_subscribers:
                self._info.put(self._camera_info(now_ns))
            if self._image.has_subscribers and self.rig.failure is None:
                self.skipped += self._waiting  # real time: the physics never waits for a frame
                self._waiting = True
        if self._waiting:
            self._request(now_ns)
        if self.index == len(self.rig.cameras) - 1:
            self.rig.deliver()

    def _request(self, now_ns: int) -> None:
        rig = self.rig
        if rig.failure is not None or not rig.ready() or rig.pool is None or not rig.accepting(now_ns):
            return
        self._waiting = False
        try:
            rig.pool.request(self.index, now_ns, self._physics.frame_pose(*self._where), rig.states(now_ns))
        except RuntimeError as exc:
            rig.fail(str(exc))

    def publish(self, frame: Frame) -> None:
        """A rendered frame out, stamped with the sim time it shows (camera_info went out at that tick)."""
        self._image.put(messages.image(frame.stamp_ns, self._frame, frame.pixels))
        self.published(frame.stamp_ns)

    def _camera_info(self, stamp_ns: int) -> messages.CameraInfo:
        spec = self.spec
        cx, cy = (spec.width - 1) / 2.0, (spec.height - 1) / 2.0
        return messages.camera_info(stamp_ns, self._frame, spec.width, spec.height, spec.fx, spec.fx, cx, cy)

    def report(self) -> dict[str, Any]:
        figures = super().report() | {"skipped": self.skipped, "size": [self.spec.width, self.spec.height]}
        if self.rig.pool is not None:
            figures["renderer"] = self.rig.pool.renderer_used
        if self.rig.failure is not None:
            figures["error"] = self.rig.failure
        return figures

    def reset(self, now_ns: int) -> None:
        super().reset(now_ns)
        self.skipped = 0
        self._waiting = False
        self.rig.forget()

    def close(self) -> None:
        if self.index == 0:
            self.rig.close()
