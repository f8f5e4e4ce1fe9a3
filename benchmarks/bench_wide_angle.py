"""Benchmark of what a wide-angle camera costs per frame against a colour camera of the same size,
in the same run: both rendered by one render worker (the server's `RenderPool`) from the tug's
front camera in the warehouse, the figure being the worker's seconds per frame (scene update,
every cube face drawn, the remap; `Frame.render_s`), and their ratio.

The wide-angle cameras are 180° equidistant lenses cut off at 90° (five cube faces) with
`<env_texture_size>` 256 (SDF's default) and 512 (gz-sim's example world).

    python benchmarks/bench_wide_angle.py [--size W H] [--frames N] [--renderer auto|gl|tiny]
"""

from __future__ import annotations

import argparse
import logging
import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from in_process import camera_mounts, in_process_server, systems_of
from tables import publish

from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.render import CameraSpec, RenderPool
from simbot.sim.render.wide_lens import WideLens
from simbot.sim.systems.camera_rendering import Rendering

log = logging.getLogger("bench_wide_angle")

FACES = (256, 512)


def cameras(width: int, height: int) -> list[CameraSpec]:
    """The colour camera (the tug's 60° field) and a wide-angle one for each face size."""
    colour = CameraSpec("colour", width, height, 1.047, 0.1, 100.0)
    wide = [
        CameraSpec(
            f"wide {face}",
            width,
            height,
            math.pi,
            0.1,
            100.0,
            outputs=("wide_color",),
            wide=WideLens("equidistant", 1.0, 1.0, 0.0, 1.0, "id", face=face),
        )
        for face in FACES
    ]
    return [colour, *wide]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(640, 480), metavar=("W", "H"))
    parser.add_argument("--frames", type=int, default=30, help="frames of each camera, after one to warm up")
    parser.add_argument("--renderer", default="auto", choices=("auto", "gl", "tiny"))
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    with in_process_server() as (server, _):
        physics = server.physics
        bodies = [scene_body(physics, name) for name in physics.body_names()]
        light = systems_of(server, Rendering)[0].light
        pose = physics.frame_pose(*camera_mounts(physics)[0])
        specs = cameras(*args.size)
        pool = RenderPool(bodies, specs, workers=1, renderer=args.renderer, light=light)
        try:
            seconds: dict[str, list[float]] = {spec.name: [] for spec in specs}
            for frame in range(args.frames + 1):
                for index, spec in enumerate(specs):  # interleaved: a busy machine slows each alike
                    pool.request(index, frame, pose, {})
                    done = pool.collect(wait_for=index, timeout=120.0)
                    if frame:
                        seconds[spec.name].extend(f.render_s for f in done if f.camera == index)
            device = pool.device
        finally:
            pool.close()
    base = statistics.median(seconds["colour"])
    table = [
        f"| camera, {args.size[0]}×{args.size[1]}, one worker on {device}, median of {args.frames} frames "
        "| a frame | ÷ the colour camera |",
        "| --- | --- | --- |",
    ]
    for name, values in seconds.items():
        median = statistics.median(values)
        table.append(f"| {name} | {median * 1000:.1f} ms | {median / base:.2f} |")
    publish("wide_angle", table)


if __name__ == "__main__":
    main()
