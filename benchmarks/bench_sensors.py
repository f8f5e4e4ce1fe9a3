"""Benchmark of the sensors: camera throughput against rendering capacity, real-time factor with
every sensor subscribed, fast mode with lidars and IMU, and each sensor's cost against the bare
PyBullet call it is built on.

Every figure is a ratio against a baseline measured in the same run, so it holds even where the
machine is shared and noisy:

1. rendering capacity: bare render loops in this process, in the warehouse with the robot, from
   the robot's six camera poses in turn: TinyRenderer (`getCameraImage` with the same arguments
   the render workers use) and the OpenGL renderer (`GlRenderer` on the same scene, reading the
   pixels back), in frames per CPU second; capacity is the renderer's frames per wall second on
   one core times the render workers that fit (`plan_pool(6)`);
2. real time, every sensor subscribed (six cameras at 640×480, then at 320×240, lidars, IMU):
   the physics real-time factor (sim-time advance / wall time over the window) and the images
   a client receives per wall second, against that capacity; the server's and the workers' CPU
   time over the window says where the time went;
3. real time with nothing subscribed: the reference real-time factor;
4. fast mode, lidars and IMU subscribed (no camera: nothing is rendered), driving: the real-time
   factor against bench_server.py's bare PyBullet loop with the wheels driven;
5. per-sensor cost, in-process on a `Server` built as `simbot-server` builds it: a lidar scan
   (pose, ray batch, noise, encode, publish) against a bare `rayTestBatch` of the same rays; an
   IMU sample (pose, velocity, noise, encode, publish) against a bare `getLinkState` with link
   velocity; a camera image (the worker's render: scene update, render, conversion, copy into
   shared memory; plus the server's request and its encode + publish) against a bare
   `getCameraImage`.

The client counts samples without decoding them: decoding 640×480 images would take CPU from
the server and its worker on a small machine, and is not the server's cost.

    python benchmarks/bench_sensors.py [--seconds S]
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import shlex
import signal
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tables import publish

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import bare_loop, free_port
from timing import per_call_ms

from simbot.bus import BusOptions, Node, messages
from simbot.description import load_model
from simbot.description.resources import asset
from simbot.sim.bullet import pb
from simbot.sim.physics import Physics
from simbot.sim.render import BodyState, CameraSpec, Light, plan_pool
from simbot.sim.render.bodies import scene_body
from simbot.sim.render.gl import GlRenderer
from simbot.sim.render.kinds import Raw
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.tiny import tiny_lighting
from simbot.sim.server import ROBOT_NAME, Server, ServerConfig, world_path
from simbot.sim.simulation import Mode
from simbot.sim.systems.camera import Camera, CameraParams
from simbot.sim.systems.imu import Imu
from simbot.sim.systems.lidar import Lidar, LidarParams, ray_fan
from simbot.sim.systems.rendering import Rendering
from simbot.transform import Transform

log = logging.getLogger("bench_sensors")

WORLD = "warehouse"
CAMERAS = tuple(s.name for _, s in load_model(asset("urdf/flexley_tug.sdf")).sensors() if s.type == "camera")
"""The tug's six cameras, read from its SDF (each publishes on its own name)."""
LIDARS = ("lidar_front", "lidar_back")
IMU = "imu_scan"
CAMERA_TARGET_HZ = 30.0
RTF_TARGET = 0.98
CAPACITY_TARGET = 0.85
FAST_TARGET = 4.0
FIRST_FRAME_TIMEOUT_S = 90.0
"""The render worker loads the warehouse before the first frame (seconds on a small machine)."""
SETTLE_S = 2.0
"""After the last camera's first frame: the real-time pacer and the pool settle."""
TICKS = os.sysconf("SC_CLK_TCK")


# --------------------------------------------------------------------------- baselines in-process


@dataclass(frozen=True)
class View:
    """One camera of the robot as the worker renders it: view and projection matrices."""

    name: str
    spec: CameraSpec
    view: Sequence[float]
    projection: Sequence[float]


def robot_views(physics: Physics, size: tuple[int, int]) -> list[View]:
    """The robot's cameras at `size`, from their world poses now: the scene content the server's
    workers render, so the bare loop draws the same triangles."""
    views = []
    for link, sensor in physics.model_of(ROBOT_NAME).sensors():
        if sensor.type != "camera":
            continue
        cam = CameraParams.from_sdf(sensor)
        spec = CameraSpec(sensor.name, size[0], size[1], cam.horizontal_fov, cam.near, cam.far)
        position, quat = physics.frame_pose(ROBOT_NAME, link.name, sensor.pose)
        rotation = np.asarray(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)
        target = np.asarray(position) + rotation[:, 0]  # the worker's convention: looks along +x, z up
        view = pb.computeViewMatrix(list(position), target.tolist(), rotation[:, 2].tolist())
        projection = pb.computeProjectionMatrixFOV(
            fov=spec.vfov_deg, aspect=size[0] / size[1], nearVal=cam.near, farVal=cam.far
        )
        views.append(View(sensor.name, spec, view, projection))
    return views


def bare_render(client: int, view: View, light: Light) -> None:
    """The render call alone, with the arguments the worker passes (rendering.py `_Scene.render`)."""
    pb.getCameraImage(
        view.spec.width,
        view.spec.height,
        view.view,
        view.projection,
        renderer=pb.ER_TINY_RENDERER,
        flags=pb.ER_NO_SEGMENTATION_MASK,
        shadow=0,
        physicsClientId=client,
        **tiny_lighting(light),
    )


def bare_render_fps(client: int, views: Sequence[View], light: Light, seconds: float) -> tuple[float, float]:
    """(frames per wall second, frames per CPU second) of TinyRenderer alone, the six cameras in
    turn. Per CPU second as well: on a shared machine the wall figure depends on the neighbours."""
    bare_render(client, views[0], light)  # first call builds TinyRenderer's buffers
    frames, start, cpu = 0, time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds or frames % len(views):
        bare_render(client, views[frames % len(views)], light)
        frames += 1
    return frames / (time.perf_counter() - start), frames / (time.process_time() - cpu)


def bare_gl_fps(physics: Physics, views: Sequence[View], light: Light, seconds: float) -> tuple[float, float, str]:
    """(frames per wall second, frames per CPU second, GL device) of the OpenGL renderer alone on
    the same scene and views, one llvmpipe thread, pixels read back into an array."""
    with gl_on(physics, views, light) as (renderer, poses):
        return (*gl_frames(renderer, poses, seconds), renderer.device)


@contextmanager
def gl_on(physics: Physics, views: Sequence[View], light: Light) -> Iterator[tuple[GlRenderer, list[Transform]]]:
    """The OpenGL renderer (one llvmpipe thread) on a copy of the server's scene, with the views'
    camera poses."""
    scene = BulletScene(pb, [scene_body(physics, name) for name in physics.body_names()])
    renderer = GlRenderer(scene, light, {i: v.spec for i, v in enumerate(views)}, threads=1)
    try:
        yield renderer, [physics.frame_pose(*where) for where in camera_mounts(physics)]
    finally:
        renderer.close()
        scene.close()


def gl_frames(renderer: GlRenderer, poses: Sequence[Transform], seconds: float) -> tuple[float, float]:
    """(frames per wall second, frames per CPU second) of the views in turn, read back into an array."""
    drawn: dict[Raw, Any] = {"color": np.zeros(renderer.targets[0].spec.drawn()["color"], dtype=np.uint8)}
    renderer.render(0, poses[0], drawn)
    frames, start, cpu = 0, time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds or frames % len(poses):
        renderer.render(frames % len(poses), poses[frames % len(poses)], drawn)
        frames += 1
    return frames / (time.perf_counter() - start), frames / (time.process_time() - cpu)


def camera_mounts(physics: Physics) -> list[tuple[str, str, Any]]:
    """(model, link, pose) of each of the robot's cameras, in SDF order."""
    return [(ROBOT_NAME, link.name, s.pose) for link, s in physics.model_of(ROBOT_NAME).sensors() if s.type == "camera"]


class Counter:
    """Samples on one key, counted on Zenoh's thread without decoding (see the module docstring)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.count = 0
        self.subscriber: object = None
        """Kept so that the subscriber lives as long as the counter."""

    def __call__(self, _sample: Any) -> None:
        with self._lock:
            self.count += 1

    def value(self) -> int:
        with self._lock:
            return self.count


def count_topics(node: Node, topics: Sequence[str]) -> dict[str, Counter]:
    """A counting subscriber per topic (it also makes the server see a subscriber: cameras render)."""
    counters = {}
    for topic in topics:
        counter = counters[topic] = Counter()
        counter.subscriber = node.session.declare_subscriber(node.key(topic), counter)
    return counters


@dataclass
class Costs:
    """Per-sensor costs (ms) and their bare PyBullet baselines (ms)."""

    lidar_ms: float = math.nan
    rays_ms: float = math.nan
    imu_ms: float = math.nan
    link_state_ms: float = math.nan
    render_ms: float = math.nan
    request_ms: float = math.nan
    publish_ms: float = math.nan
    round_trip_ms: float = math.nan
    bare_image_ms: float = math.nan
    capacity_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    """Bare frames per wall second on one core of the renderer the server uses, by image size."""
    cpu_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    """Bare frames per CPU second of the renderer the server uses, by image size."""
    tiny_cpu_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    gl_cpu_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    tiny_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    gl_fps: dict[tuple[int, int], float] = field(default_factory=dict)
    gl_device: str = "none"
    renderer: str = "tiny"
    fallback: str | None = None


@contextmanager
def in_process_server(world: str = WORLD) -> Iterator[tuple[Server, Node]]:
    """A `Server` built as simbot-server builds it (lockstep, so that starting the render pool
    waits), on its own loopback port, and a client node on it."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    config = ServerConfig(
        world_path(world),
        asset("urdf/flexley_tug.sdf"),
        mode=Mode.LOCKSTEP,
        overrides={"camera.size": (640, 480)},
    )
    with Node(BusOptions(listen=(endpoint,), namespace=namespace), "server") as node:
        server = Server(config, node)
        try:
            with Node(BusOptions(connect=(endpoint,), namespace=namespace), "client") as client:
                yield server, client
        finally:
            server.close()


def systems_of(server: Server, kind: type) -> list[Any]:
    return [s for s in server.sim.systems if isinstance(s, kind)]


def lidar_costs(server: Server, costs: Costs, repeats: int) -> None:
    """Our scan + encode + publish against the bare ray batch of the same 720 rays."""
    physics, lidar = server.physics, systems_of(server, Lidar)[0]
    now = server.sim.clock.info()

    def ours() -> None:
        lidar.every.restart()  # due now: post_update does exactly what it does at each tick
        lidar.post_update(now)

    link, sensor = next((lk, s) for lk, s in physics.model_of(ROBOT_NAME).sensors() if s.name == lidar.name)
    params = LidarParams.from_sdf(sensor)
    position, quat = physics.frame_pose(ROBOT_NAME, link.name, sensor.pose)
    fan = ray_fan(params)
    directions = fan.directions[fan.scan_row] @ np.asarray(pb.getMatrixFromQuaternion(quat)).reshape(3, 3).T
    starts = (np.asarray(position) + directions * params.range_min).tolist()
    ends = (np.asarray(position) + directions * params.range_max).tolist()
    client, mask = physics.client, ~physics.blind_rays_to(ROBOT_NAME)
    costs.lidar_ms = per_call_ms(ours, repeats)
    costs.rays_ms = per_call_ms(
        lambda: pb.rayTestBatch(starts, ends, collisionFilterMask=mask, physicsClientId=client), repeats
    )


def imu_costs(server: Server, costs: Costs, repeats: int) -> None:
    """Our sample + encode + publish against one bare getLinkState with the link's velocity."""
    physics, imu = server.physics, systems_of(server, Imu)[0]
    now = server.sim.clock.info()

    def ours() -> None:
        imu.every.restart()
        imu.post_update(now)

    body = physics.body(ROBOT_NAME)
    link = next(lk for lk, s in body.model.sensors() if s.name == imu.name)
    index, client = body.links[link.name], physics.client
    costs.imu_ms = per_call_ms(ours, repeats)
    costs.link_state_ms = per_call_ms(lambda: bare_link_state(body.id, index, client), repeats)


def bare_link_state(body: int, index: int, client: int) -> None:
    """PyBullet's pose and velocity of one link: getLinkState, or for the base (where the lean
    loader merges the IMU's link, index -1) getBasePositionAndOrientation and getBaseVelocity."""
    if index == -1:
        pb.getBasePositionAndOrientation(body, physicsClientId=client)
        pb.getBaseVelocity(body, physicsClientId=client)
    else:
        pb.getLinkState(body, index, computeLinkVelocity=1, physicsClientId=client)


def camera_costs(server: Server, costs: Costs, rounds: int) -> None:
    """Each camera through the real pool: the server's request (pose, body states, pipe), the
    worker's render (Frame.render_s), and the server's encode + publish (Camera.publish)."""
    physics, cameras, rendering = server.physics, systems_of(server, Camera), systems_of(server, Rendering)[0]
    if not rendering._ready() or rendering.pool is None:
        raise RuntimeError(f"render pool did not start: {rendering.status.failure}")
    pool = rendering.pool
    costs.renderer, costs.fallback = pool.renderer_used, pool.fallback_reason
    request, render, publish, trip = [], [], [], []
    for n in range(rounds + 1):
        for cam in cameras:
            now = (
                server.sim.clock.now_ns + n * len(cameras) + rendering.cameras.index(cam)
            )  # a fresh snapshot each time
            start = time.perf_counter()
            states = {name: BodyState(*physics.body_state(name)) for name in physics.moving_bodies()}
            pool.request(rendering.cameras.index(cam), now, physics.frame_pose(*cam.where), states)
            requested = time.perf_counter()
            (frame,) = pool.collect(wait_for=rendering.cameras.index(cam), timeout=FIRST_FRAME_TIMEOUT_S)
            collected = time.perf_counter()
            cam.publish(frame)
            published = time.perf_counter()
            if n:  # round 0 warms the worker's buffers
                request.append(requested - start)
                render.append(frame.render_s)
                publish.append(published - collected)
                trip.append(collected - start)
    # means: the six views cost different amounts, and the bare figure is the mean over them too
    costs.request_ms, costs.render_ms = statistics.mean(request) * 1e3, statistics.mean(render) * 1e3
    costs.publish_ms, costs.round_trip_ms = statistics.mean(publish) * 1e3, statistics.mean(trip) * 1e3


def measure_in_process(seconds: float) -> Costs:
    """Rendering capacity and per-sensor costs, with no server process running."""
    costs = Costs()
    log.info("in-process: building the warehouse server")
    with in_process_server() as (server, client):
        count_topics(client, [*CAMERAS, *LIDARS, IMU])  # the bytes really leave, as they do for a subscriber
        time.sleep(0.5)
        light = systems_of(server, Rendering)[0].light
        for size in ((640, 480), (320, 240)):
            views = robot_views(server.physics, size)
            costs.tiny_fps[size], costs.tiny_cpu_fps[size] = bare_render_fps(
                server.physics.client, views, light, seconds
            )
            log.info("bare TinyRenderer %dx%d: %.1f frames/s on one core", *size, costs.tiny_fps[size])
            costs.gl_fps[size], costs.gl_cpu_fps[size], costs.gl_device = bare_gl_fps(
                server.physics, views, light, seconds
            )
            log.info("bare GL %dx%d: %.1f frames/s on one core (%s)", *size, costs.gl_fps[size], costs.gl_device)
        lidar_costs(server, costs, 100)
        imu_costs(server, costs, 2000)
        log.info("in-process: starting the render pool for the camera costs")
        camera_costs(server, costs, 3)
        bare = costs.gl_fps if costs.renderer == "gl" else costs.tiny_fps
        costs.capacity_fps = bare
        costs.cpu_fps = costs.gl_cpu_fps if costs.renderer == "gl" else costs.tiny_cpu_fps
        costs.bare_image_ms = 1e3 / bare[(640, 480)]  # the mean over the six views, as render_ms
    return costs


# --------------------------------------------------------------------------- the server process


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of one process so far (/proc/<pid>/stat utime, stime)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as file:
            fields = file.read().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / TICKS


def schedstat(pid: int) -> tuple[float, float]:
    """(seconds on a CPU, seconds runnable but waiting for one) of one thread so far
    (/proc/<pid>/schedstat; the process id names its main thread, where the physics loop runs)."""
    try:
        with open(f"/proc/{pid}/schedstat", encoding="ascii") as file:
            on_cpu, waiting = file.read().split()[:2]
    except (OSError, ValueError):
        return math.nan, math.nan
    return int(on_cpu) / 1e9, int(waiting) / 1e9


def children(pid: int) -> dict[int, str]:
    """The server's child processes (render workers, multiprocessing's resource tracker), by role."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="ascii") as file:
                ppid = int(file.read().rsplit(")", 1)[1].split()[1])
            if ppid != pid:
                continue
            with open(f"/proc/{entry}/cmdline", "rb") as file:
                cmdline = file.read().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, ValueError, IndexError):
            continue
        found[int(entry)] = "resource tracker" if "resource_tracker" in cmdline else "render worker"
    return found


def machine_busy() -> tuple[float, float]:
    """(busy, total) jiffies of all cores so far (/proc/stat): how saturated the machine was."""
    with open("/proc/stat", encoding="ascii") as file:
        values = [int(v) for v in file.readline().split()[1:]]
    idle = values[3] + values[4]
    return sum(values) - idle, sum(values)


@dataclass
class Run:
    """What one server run achieved over its measuring window."""

    wall_s: float
    rtf: float
    """Sim seconds advanced per wall second over the window."""
    state_rtf: float
    """The server's own one-second real-time factor at the end of the window."""
    received: dict[str, int]
    """Samples the client received per topic in the window."""
    sensors: dict[str, dict[str, float]]
    """Per sensor: messages and skipped in the window (world state), and its reported rate_hz."""
    server_cpu: float
    """CPU seconds per wall second of the server process (physics thread + Zenoh threads)."""
    loop_cpu: float
    """CPU seconds per wall second of the server's main thread (the simulation loop)."""
    loop_wait: float
    """Seconds per wall second the main thread was runnable but had no CPU."""
    worker_cpu: float
    """CPU seconds per wall second of all render workers together."""
    worker_wait: float
    """Seconds per wall second the render workers were runnable but had no CPU."""
    client_cpu: float
    """CPU seconds per wall second of this benchmark process (the counting client)."""
    machine_busy: float
    """Busy fraction of all cores."""
    cores: int
    intervals: list[float]
    """Real-time factor of each half second of the window: whether time was lost evenly or in stalls."""
    renderer: str | None = None

    @property
    def others_cpu(self) -> float:
        """Cores' worth of CPU that processes outside this benchmark took (a shared machine)."""
        return self.machine_busy * self.cores - self.server_cpu - self.worker_cpu - self.client_cpu

    def per_second(self, topic: str) -> float:
        return self.received.get(topic, 0) / self.wall_s


def _connect(endpoint: str, namespace: str, proc: subprocess.Popen[bytes]) -> Node:
    deadline = time.monotonic() + 30
    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"simbot-server exited with code {proc.returncode} at start")
        try:
            return Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=1.0), "client")
        except OSError:
            if time.monotonic() > deadline:
                raise


def _state(node: Node) -> dict[str, Any]:
    return node.call(f"world/{WORLD}/state", {}, timeout=5.0)


def _wait_ready(node: Node) -> None:
    deadline = time.monotonic() + 30
    while True:
        try:
            if _state(node).get("ok"):
                return
        except (TimeoutError, RuntimeError):
            pass
        if time.monotonic() > deadline:
            raise RuntimeError("the server's world control did not answer within 30 s")
        time.sleep(0.05)


def _wait_first(counters: dict[str, Counter], topics: Sequence[str], proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + FIRST_FRAME_TIMEOUT_S
    while not all(counters[t].value() for t in topics):
        if proc.poll() is not None or time.monotonic() > deadline:
            missing = [t for t in topics if not counters[t].value()]
            raise RuntimeError(f"no message on {missing} within {FIRST_FRAME_TIMEOUT_S:.0f} s")
        time.sleep(0.1)


def run_server(
    mode: str,
    topics: Sequence[str],
    seconds: float,
    extra: Sequence[str] = (),
    drive: bool = False,
    world: str = WORLD,
    clients: Sequence[str] | None = None,
) -> Run:
    """`simbot-server` on a fresh loopback port and namespace, `topics` subscribed; measured over
    `seconds` of wall time once every subscribed topic has delivered and the loop has settled.
    `world`: a name or an SDF path whose `<world>` is named warehouse (world control's key).
    `clients`: the server started by `simbot launch` with these clients, as `make run` starts it."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    server = ["--mode", mode, "--quiet", *extra]
    if clients is None:
        command = [sys.executable, "-m", "simbot.sim.server", "--world", world, *server]
    else:
        launch = ["launch", "--world", world, "--clients", ",".join(clients), f"--server-args={shlex.join(server)}"]
        command = [sys.executable, "-m", "simbot.cli", *launch]
    bus = ["--listen", endpoint, "--namespace", namespace]
    proc = subprocess.Popen([*command, *bus], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with _connect(endpoint, namespace, proc) as node:
            _wait_ready(node)
            counters = count_topics(node, topics)
            if drive:
                node.publisher("cmd_vel", drop=False).put(messages.twist((0.3, 0.0, 0.0), (0.0, 0.0, 0.1)))
            _wait_first(counters, topics, proc)
            time.sleep(SETTLE_S)
            return _measure(node, proc.pid if clients is None else _server_pid(proc.pid), counters, seconds)
    finally:
        proc.send_signal(signal.SIGINT)  # launch ends its children on Ctrl-C; the server ends on it too
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _server_pid(launch: int) -> int:
    """The server among launch's children."""
    for pid in children(launch):
        with open(f"/proc/{pid}/cmdline", "rb") as file:
            if b"simbot.sim.server" in file.read():
                return pid
    raise RuntimeError(f"launch (pid {launch}) runs no simbot.sim.server")


SAMPLE_S = 0.5


def _sample(node: Node, seconds: float) -> tuple[dict[str, Any], list[float]]:
    """The world state at the end of `seconds`, and the real-time factor of each half second."""
    state, wall = _state(node), time.perf_counter()
    end, intervals = wall + seconds, []
    while wall < end:
        time.sleep(max(0.0, min(SAMPLE_S, end - wall)))
        now_state, now = _state(node), time.perf_counter()
        intervals.append((now_state["sim_time"] - state["sim_time"]) / (now - wall))
        state, wall = now_state, now
    return state, intervals


def _sched(pids: Sequence[int]) -> tuple[float, float]:
    stats = [schedstat(p) for p in pids]
    return sum(s[0] for s in stats), sum(s[1] for s in stats)


def _measure(node: Node, pid: int, counters: dict[str, Counter], seconds: float) -> Run:
    workers = [p for p, role in children(pid).items() if role == "render worker"]
    before = _state(node)
    counts0 = {t: c.value() for t, c in counters.items()}
    cpu0, wcpu0, me0, busy0 = (
        cpu_seconds(pid),
        sum(cpu_seconds(w) for w in workers),
        time.process_time(),
        machine_busy(),
    )
    loop0, wsched0 = schedstat(pid), _sched(workers)
    wall0 = time.perf_counter()
    after, intervals = _sample(node, seconds)
    wall = time.perf_counter() - wall0
    cpu1, wcpu1, me1, busy1 = (
        cpu_seconds(pid),
        sum(cpu_seconds(w) for w in workers),
        time.process_time(),
        machine_busy(),
    )
    loop1, wsched1 = schedstat(pid), _sched(workers)
    counts = {t: c.value() - counts0[t] for t, c in counters.items()}
    sensors = {}
    for name, figures in after["sensors"].items():
        old = before["sensors"].get(name, {})
        sensors[name] = {
            "messages": figures.get("messages", 0) - old.get("messages", 0),
            "skipped": figures.get("skipped", 0) - old.get("skipped", 0),
            "rate_hz": figures.get("rate_hz", 0.0),
        }
    renderer = next((f["renderer"] for f in after["sensors"].values() if "renderer" in f), None)
    return Run(
        wall_s=wall,
        rtf=(after["sim_time"] - before["sim_time"]) / wall,
        state_rtf=after["real_time_factor"],
        received=counts,
        sensors=sensors,
        server_cpu=(cpu1 - cpu0) / wall,
        loop_cpu=(loop1[0] - loop0[0]) / wall,
        loop_wait=(loop1[1] - loop0[1]) / wall,
        worker_cpu=(wcpu1 - wcpu0) / wall,
        worker_wait=(wsched1[1] - wsched0[1]) / wall,
        client_cpu=(me1 - me0) / wall,
        machine_busy=(busy1[0] - busy0[0]) / max(1, busy1[1] - busy0[1]),
        cores=len(os.sched_getaffinity(0)),
        intervals=intervals,
        renderer=renderer,
    )


# --------------------------------------------------------------------------- report


def camera_fps(run: Run) -> float:
    """Images per wall second the client received, all cameras together."""
    return sum(run.per_second(c) for c in CAMERAS)


def verdict(ok: bool) -> str:
    return "PASS" if ok else "NOT REACHED"


def describe(label: str, run: Run) -> None:
    """The raw figures of one run."""
    print(
        f"\n{label}: {run.wall_s:.1f} s wall, rtf {run.rtf:.3f} (server's 1 s window {run.state_rtf:.3f}), "
        f"renderer {run.renderer}"
    )
    slow = [f"{r:.2f}" for r in run.intervals if r < RTF_TARGET]
    print(
        f"  half-second real-time factors: min {min(run.intervals):.3f}, median {statistics.median(run.intervals):.3f}; "
        f"{len(slow)} of {len(run.intervals)} below {RTF_TARGET}: {' '.join(slow) or '-'}"
    )
    print(
        f"  CPU per wall second: server {run.server_cpu:.2f} (its loop thread {run.loop_cpu:.2f}, runnable without a CPU "
        f"{run.loop_wait:.3f}), render workers {run.worker_cpu:.2f} (runnable without a CPU {run.worker_wait:.2f}), "
        f"this client {run.client_cpu:.2f}, other processes on the machine {run.others_cpu:.2f}; "
        f"machine busy {run.machine_busy:.0%} of {run.cores} cores"
    )
    for topic, count in run.received.items():
        figures = run.sensors.get(topic.replace("imu_scan", "imu_sensor"), {})
        print(
            f"  {topic:20s} received {count:5d} ({count / run.wall_s:6.2f}/s wall); server: "
            f"{figures.get('messages', 0):5.0f} published, {figures.get('skipped', 0):5.0f} skipped, "
            f"rate {figures.get('rate_hz', 0):.2f} Hz sim"
        )


@dataclass(frozen=True)
class BareLoop:
    """bench_server.py's bare PyBullet loop, with the share of a core it got."""

    rtf: float
    cpu: float
    """CPU seconds per wall second this process got while it ran."""


def bare_physics(seconds: float) -> BareLoop:
    """The fast-mode baseline: bench_server.py's loop with the wheels driven, as the server drives."""
    wall, cpu = time.perf_counter(), time.process_time()
    rtf = bare_loop(seconds, driving=True)
    return BareLoop(rtf, (time.process_time() - cpu) / (time.perf_counter() - wall))


def _rtf_row(label: str, run: Run, idle: Run) -> tuple[str, str, str, str]:
    return (
        f"real time, all sensors, 6 cameras {label}: real-time factor",
        f"{run.rtf:.3f} ({verdict(run.rtf >= RTF_TARGET)}; worst half second {min(run.intervals):.2f})",
        f"≥ {RTF_TARGET}",
        f"{idle.rtf:.3f} with nothing subscribed",
    )


def _camera_rows(
    label: str, run: Run, costs: Costs, size: tuple[int, int], workers: int
) -> list[tuple[str, str, str, str]]:
    capacity, fps = costs.capacity_fps[size] * workers, camera_fps(run)
    wanted = min(capacity, CAMERA_TARGET_HZ * len(CAMERAS))  # beyond 30 Hz a camera has nothing more to render
    per_cpu = fps / run.worker_cpu if run.worker_cpu > 0 else math.nan
    return [
        (
            f"real time, 6 cameras {label}: images/s received, all cameras",
            f"{fps:.1f} = {fps / wanted:.0%} of min(capacity, 6 × 30 Hz) ({verdict(fps >= CAPACITY_TARGET * wanted)})",
            f"≥ {CAPACITY_TARGET:.0%} of min(capacity, 180/s)",
            f"capacity {capacity:.1f}/s = bare {costs.renderer} {costs.capacity_fps[size]:.1f}/s × {workers} worker(s)",
        ),
        (
            f"real time, 6 cameras {label}: images per render-worker CPU second",
            f"{per_cpu:.1f} = {per_cpu / costs.cpu_fps[size]:.0%} of bare "
            f"(workers got {run.worker_cpu:.2f} of a core each second)",
            "—",
            f"bare {costs.renderer} {costs.cpu_fps[size]:.1f} per CPU second",
        ),
    ]


def _per_camera(label: str, run: Run, target: float) -> tuple[str, str, str, str]:
    rates = [run.per_second(c) for c in CAMERAS]
    return (
        f"real time, {label}: images/s per camera (front, back, front_right, back_right, front_left, back_left)",
        ", ".join(f"{r:.1f}" for r in rates) + f" ({verdict(min(rates) >= target)})",
        f"≥ {target:.0f} each",
        f"{CAMERA_TARGET_HZ:.0f} Hz in the SDF",
    )


def table(
    costs: Costs, workers: int, idle: Run, big: Run, small: Run, big_tiny: Run, fast: Run, bare: BareLoop
) -> list[str]:
    """One markdown table, ready for the README."""
    gl_over_tiny = costs.gl_cpu_fps[(640, 480)] / costs.tiny_cpu_fps[(640, 480)]
    image_ms = costs.request_ms + costs.render_ms + costs.publish_ms
    fast_per_cpu, bare_per_cpu = fast.rtf / fast.server_cpu, bare.rtf / bare.cpu
    rows = [
        (
            "GL renderer, 640×480 warehouse frame, six poses: frames per CPU second",
            f"{costs.gl_cpu_fps[(640, 480)]:.0f} = {gl_over_tiny:.1f}× TinyRenderer ({verdict(gl_over_tiny >= 10)})",
            "≥ 10×",
            f"bare TinyRenderer {costs.tiny_cpu_fps[(640, 480)]:.1f} per CPU second ({costs.gl_device})",
        ),
        ("real time, nothing subscribed: real-time factor", f"{idle.rtf:.3f}", "1.0", "—"),
        _rtf_row(f"640×480 ({big.renderer})", big, idle),
        _per_camera(f"6 cameras 640×480 ({big.renderer})", big, 25.0),
        *_camera_rows(f"640×480 ({big.renderer})", big, costs, (640, 480), workers),
        _rtf_row(f"320×240 ({small.renderer})", small, idle),
        _per_camera(f"6 cameras 320×240 ({small.renderer})", small, 29.0),
        _rtf_row(f"640×480 ({big_tiny.renderer})", big_tiny, idle),
        _per_camera(f"6 cameras 640×480 ({big_tiny.renderer})", big_tiny, 25.0),
        (
            "fast mode, lidars + IMU subscribed, driving: real-time factor",
            f"{fast.rtf:.1f}× = {fast.rtf / bare.rtf:.2f} of bare ({verdict(fast.rtf >= FAST_TARGET)})",
            f"≥ {FAST_TARGET:.0f}×",
            f"bare PyBullet 1 kHz loop, wheels driven: {bare.rtf:.1f}×",
        ),
        (
            "fast mode, lidars + IMU: sim seconds per server CPU second",
            f"{fast_per_cpu:.1f} = {fast_per_cpu / bare_per_cpu:.2f} of bare (server got {fast.server_cpu:.2f} of a core)",
            "—",
            f"bare loop {bare_per_cpu:.1f} per CPU second (it got {bare.cpu:.2f} of a core)",
        ),
        (
            "lidar scan (720 rays, noise, encode, publish)",
            f"{costs.lidar_ms:.2f} ms = {costs.lidar_ms / costs.rays_ms:.2f}× bare",
            "—",
            f"bare rayTestBatch, 720 rays: {costs.rays_ms:.2f} ms",
        ),
        (
            "IMU sample (pose, velocity, noise, encode, publish)",
            f"{costs.imu_ms * 1e3:.0f} µs = {costs.imu_ms / costs.link_state_ms:.0f}× bare",
            "—",
            f"bare pose and velocity of its link: {costs.link_state_ms * 1e3:.1f} µs",
        ),
        (
            "camera image 640×480, mean of the six (server request + worker render + server encode, publish)",
            f"{costs.request_ms:.2f} + {costs.render_ms:.1f} + {costs.publish_ms:.2f} = {image_ms:.1f} ms"
            f" = {image_ms / costs.bare_image_ms:.2f}× bare",
            "—",
            f"bare getCameraImage 640×480, mean of the six views: {costs.bare_image_ms:.1f} ms",
        ),
    ]
    lines = ["| measurement | result | target | baseline in the same run |", "| --- | --- | --- | --- |"]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seconds", type=float, default=10.0, help="wall seconds per camera measurement (others take half)"
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    short = args.seconds / 2
    workers = plan_pool(len(CAMERAS)).workers

    costs = measure_in_process(short / 2)
    log.info("server: real time, nothing subscribed")
    idle = run_server("realtime", [], short)
    everything = [*CAMERAS, *LIDARS, IMU]
    log.info("server: real time, every sensor subscribed, 640x480")
    big = run_server("realtime", everything, args.seconds, ["--camera-size", "640x480"])
    log.info("server: real time, every sensor subscribed, 320x240")
    small = run_server("realtime", everything, args.seconds, ["--camera-size", "320x240"])
    log.info("server: real time, every sensor subscribed, 640x480, TinyRenderer")
    big_tiny = run_server("realtime", everything, args.seconds, ["--camera-size", "640x480", "--renderer", "tiny"])
    log.info("server: fast mode, lidars and IMU, driving")
    fast = run_server("fast", [*LIDARS, IMU], short, drive=True)
    log.info("bare PyBullet loop, wheels driven")
    bare = bare_physics(short)

    print()
    publish("sensors", table(costs, workers, idle, big, small, big_tiny, fast, bare))
    fallback = f", fell back: {costs.fallback}" if costs.fallback else ", no fallback"
    print(
        f"\nraw: {workers} render worker(s) on {len(os.sched_getaffinity(0))} cores; renderer {costs.renderer}{fallback}"
    )
    print(f"  camera round trip (request to collected, in-process, worker alone): {costs.round_trip_ms:.1f} ms")
    for size in costs.tiny_fps:
        print(
            f"  bare TinyRenderer {size[0]}x{size[1]}: {costs.tiny_fps[size]:.1f}/s wall, {costs.tiny_cpu_fps[size]:.1f}/s CPU"
        )
        print(
            f"  bare GL {size[0]}x{size[1]}: {costs.gl_fps[size]:.1f}/s wall, {costs.gl_cpu_fps[size]:.1f}/s CPU ({costs.gl_device})"
        )
    print(f"  bare PyBullet loop, wheels driven: {bare.rtf:.2f}× real time with {bare.cpu:.2f} of a core")
    runs = {
        "real time, nothing subscribed": idle,
        "real time, 640x480": big,
        "real time, 320x240": small,
        "real time, 640x480, TinyRenderer": big_tiny,
        "fast, lidars + IMU": fast,
    }
    for label, run in runs.items():
        describe(label, run)


if __name__ == "__main__":
    main()
