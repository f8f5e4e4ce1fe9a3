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
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tables import publish

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import bare_loop
from in_process import bare_gl_fps, bare_render_fps, in_process_server, robot_views, systems_of
from live_runs import (
    CAMERAS,
    FIRST_FRAME_TIMEOUT_S,
    IMU,
    LIDARS,
    RTF_TARGET,
    Run,
    camera_fps,
    count_topics,
    describe,
    run_server,
    verdict,
)
from timing import per_call_ms

from simbot.description.lidar_params import LidarParams
from simbot.sim.bullet import pb
from simbot.sim.render import BodyState, plan_pool
from simbot.sim.server import ROBOT_NAME, Server
from simbot.sim.systems.camera import Camera
from simbot.sim.systems.camera_rendering import Rendering
from simbot.sim.systems.imu import Imu
from simbot.sim.systems.lidar import Lidar, ray_fan

log = logging.getLogger("bench_sensors")

CAMERA_TARGET_HZ = 30.0
CAPACITY_TARGET = 0.85
FAST_TARGET = 4.0


# --------------------------------------------------------------------------- baselines in-process


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
    client, mask = physics.client, ~physics._rays.bullet.blind_to(physics.body(ROBOT_NAME))
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
