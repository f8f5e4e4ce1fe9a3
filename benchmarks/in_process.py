"""simbot's server and its renderers in the benchmark's own process: a `Server` built as
`simbot-server` builds it, its systems, the robot's camera views, and the renderers drawing them
alone (TinyRenderer through PyBullet, the OpenGL renderer on a copy of the scene), so that a cost
is measured without a process boundary or a busy server around it.
"""

from __future__ import annotations

import sys
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_server import free_port
from live_runs import WORLD

from simbot.bus import BusOptions, Node
from simbot.description.resources import asset
from simbot.sim.bullet import pb
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.loop.simulation import Mode
from simbot.sim.physics import Physics
from simbot.sim.render import CameraSpec, Light
from simbot.sim.render.gl import GlRenderer
from simbot.sim.render.kinds import Raw
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.tiny import tiny_lighting
from simbot.sim.server import ROBOT_NAME, Server, ServerConfig, world_path
from simbot.sim.systems.camera import CameraParams
from simbot.transform import Transform


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
    """The render call alone, with the arguments the worker passes (the worker's `render`)."""
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
