"""Benchmark of the thermal camera: what one frame costs against a colour camera of the same size,
in the same run, as a ratio (the figure a shared, noisy machine moves least).

A copy of the warehouse gets a rig in its aisle holding two cameras at one pose, 640×480 (the size
the tug's cameras run at): `eye`, a colour camera, and `heat`, an L16 thermal camera (the Thermal
system on the rig's own box, so the scene holds an annotated visual). An in-process `Server` built
as simbot-server builds it (in_process.py's `in_process_server`) renders them in turn through
its render pool; each frame's worker time (`Frame.render_s`: scene update, draw, read-back and the
finishing steps: the thermal counts) and the server's message build (rgb8 against mono16) are
taken, medians over the rounds.

    python benchmarks/bench_thermal.py [--rounds N]
"""

from __future__ import annotations

import argparse
import logging
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_looks import resources_from
from in_process import in_process_server, systems_of
from live_runs import FIRST_FRAME_TIMEOUT_S
from tables import publish

from simbot.description.resources import asset
from simbot.sim.render import BodyState
from simbot.sim.server import Server
from simbot.sim.systems.camera import Camera
from simbot.sim.systems.camera_rendering import Rendering

log = logging.getLogger("bench_thermal")

SIZE = (640, 480)
CAMERA = """<sensor name="{name}" type="{kind}"><update_rate>30</update_rate><topic>{name}</topic>
  <camera><horizontal_fov>1.2</horizontal_fov><image><width>{w}</width><height>{h}</height><format>{format}</format>
  </image><clip><near>0.1</near><far>40</far></clip></camera></sensor>"""
RIG = """<model name="rig"><static>true</static><pose>0 0 1.2 0 0 0.4</pose><link name="mount">
  <visual name="box"><geometry><box><size>0.1 0.1 0.1</size></box></geometry>
    <plugin name="gz::sim::systems::Thermal" filename="gz-sim-thermal-system"><temperature>320</temperature></plugin>
  </visual>{cameras}</link></model>"""


def rigged_world(folder: Path) -> Path:
    """A copy of worlds/ under `folder` with the rig in the warehouse; its world file."""
    shutil.copytree(asset("worlds"), folder)
    world = folder / "warehouse.sdf"
    cameras = CAMERA.format(name="eye", kind="camera", w=SIZE[0], h=SIZE[1], format="R8G8B8") + CAMERA.format(
        name="heat", kind="thermal", w=SIZE[0], h=SIZE[1], format="L16"
    )
    text = world.read_text()
    world.write_text(text.replace("</world>", RIG.format(cameras=cameras) + "</world>", 1))
    return world


def frame_costs(server: Server, names: tuple[str, ...], rounds: int) -> dict[str, tuple[float, float]]:
    """Each named camera's median worker ms per frame and server ms per message build, the cameras
    taken in turn each round (round 0 warms the worker's buffers and is not counted)."""
    rendering = systems_of(server, Rendering)[0]
    if not rendering._ready() or rendering.pool is None:
        raise RuntimeError(f"render pool did not start: {rendering.status.failure}")
    cameras = {cam.name: cam for cam in systems_of(server, Camera) if cam.name in names}
    render: dict[str, list[float]] = {name: [] for name in names}
    build: dict[str, list[float]] = {name: [] for name in names}
    physics, pool = server.physics, rendering.pool
    for n in range(rounds + 1):
        for name in names:
            cam, index = cameras[name], rendering.cameras.index(cameras[name])
            states = {body: BodyState(*physics.body_state(body)) for body in physics.moving_bodies()}
            pool.request(
                index, server.sim.clock.now_ns + n * len(names) + index, physics.frame_pose(*cam.where), states
            )
            (frame,) = pool.collect(wait_for=index, timeout=FIRST_FRAME_TIMEOUT_S)
            output = cam.outputs[0]
            start = time.perf_counter()
            output.build(frame.stamp_ns, cam.frame_id, frame[output.output])
            if n:
                build[name].append(time.perf_counter() - start)
                render[name].append(frame.render_s)
    return {name: (statistics.median(render[name]) * 1e3, statistics.median(build[name]) * 1e3) for name in names}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=60, help="frames of each camera (default 60)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    with tempfile.TemporaryDirectory(prefix="bench-thermal-") as tmp:
        world = rigged_world(Path(tmp) / "worlds")
        with resources_from(world.parent / "models"), in_process_server(str(world)) as (server, _client):
            renderer = systems_of(server, Rendering)[0]
            log.info("rendering %d rounds of eye and heat at %dx%d", args.rounds, *SIZE)
            costs = frame_costs(server, ("eye", "heat"), args.rounds)
            used = renderer.pool.renderer_used if renderer.pool else "none"
    (eye_render, eye_build), (heat_render, heat_build) = costs["eye"], costs["heat"]
    print(f"thermal camera against a colour camera, {SIZE[0]}x{SIZE[1]}, renderer {used}, medians of {args.rounds}:")
    publish(
        "thermal",
        [
            f"| {SIZE[0]}×{SIZE[1]}, renderer {used}, median of {args.rounds} | colour | thermal | thermal ÷ colour |",
            "| --- | --- | --- | --- |",
            f"| worker, a frame | {eye_render:.2f} ms | {heat_render:.2f} ms | {heat_render / eye_render:.2f} |",
            f"| server, a build | {eye_build:.2f} ms | {heat_build:.2f} ms | {heat_build / eye_build:.2f} |",
        ],
    )


if __name__ == "__main__":
    main()
