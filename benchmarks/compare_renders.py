"""How far this tree's OpenGL renderer draws the warehouse from another revision's: the robot's
six cameras at 640×480 (colour, depth and labels), each drawn by both, pixel by pixel.

A change to the renderer that should only reorder or batch its draws may still move pixels where
two surfaces lie at one depth, or where a sum rounds another way; this says how many pixels moved
and by how much. The other revision is checked out into a temporary git worktree and run in a
child process with it first on the path; both draw in the same warehouse at the same poses, one
llvmpipe thread each.

    python benchmarks/compare_renders.py [--against REV]   (default: HEAD)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SIZE = (640, 480)
OUTPUTS = ("color", "depth")


def draw(folder: Path) -> None:
    """The six views' colour and depth into `folder` as .npy, drawn by the simbot first on the path
    (only what both revisions have is used here)."""
    from simbot.bus import BusOptions, Node
    from simbot.description.resources import asset
    from simbot.sim.bullet import pb
    from simbot.sim.loop.simulation import Mode
    from simbot.sim.render import CameraSpec
    from simbot.sim.render.gl import GlRenderer
    from simbot.sim.render.scene import BulletScene
    from simbot.sim.server import ROBOT_NAME, Server, ServerConfig, world_path
    from simbot.sim.systems.camera import CameraParams
    from simbot.sim.systems.camera_rendering import world_light

    config = ServerConfig(world_path("warehouse"), asset("urdf/flexley_tug.sdf"), mode=Mode.LOCKSTEP)
    with Node(BusOptions(listen=("tcp/127.0.0.1:0",)), "server") as node:
        server = Server(config, node)
        physics = server.physics
        cameras = [(link, sensor) for link, sensor in physics.model_of(ROBOT_NAME).sensors() if sensor.type == "camera"]
        specs = {}
        for index, (_link, sensor) in enumerate(cameras):
            params = CameraParams.from_sdf(sensor)
            specs[index] = CameraSpec(
                sensor.name, *SIZE, params.horizontal_fov, params.near, params.far, outputs=OUTPUTS
            )
        scene = BulletScene(pb, [_scene_body(physics, name) for name in physics.body_names()])
        renderer = GlRenderer(scene, world_light(server.world.description), specs, threads=1)
        try:
            for index, (link, sensor) in enumerate(cameras):
                drawn = {
                    kind: np.zeros(shape, dtype="u1" if kind == "color" else "f4")
                    for kind, shape in specs[index].drawn().items()
                }
                renderer.render(index, physics.frame_pose(ROBOT_NAME, link.name, sensor.pose), drawn)
                for kind, array in drawn.items():
                    np.save(folder / f"{sensor.name}_{kind}.npy", array)
        finally:
            renderer.close()
            scene.close()
            server.close()


def _scene_body(physics: Any, name: str) -> Any:
    """A body as the revision's render workers get it (`kit/scene_bodies.py`, or before it a SceneBody of the URDF)."""
    try:
        from simbot.sim.kit.scene_bodies import scene_body
    except ImportError:
        from simbot.sim.render import SceneBody

        return SceneBody(name, physics.urdf_of(name), physics.model_of(name).static, physics.body_state(name)[0])
    return scene_body(physics, name)


def compare(ours: Path, theirs: Path) -> list[str]:
    """One row per view and output: how many pixels differ, and the largest difference."""
    lines = ["| view | output | pixels that differ | largest difference |", "| --- | --- | --- | --- |"]
    for path in sorted(ours.glob("*.npy")):
        a, b = np.load(path), np.load(theirs / path.name)
        differ = ((a != b) & ~(np.isinf(a) & np.isinf(b))).reshape(a.shape[0], a.shape[1], -1).any(axis=2)
        gap = np.abs(a.astype(np.float64) - b.astype(np.float64))
        largest = float(gap[np.isfinite(gap)].max(initial=0.0))
        view, kind = path.stem.rsplit("_", 1)
        lines.append(f"| {view} | {kind} | {int(differ.sum())} of {differ.size} | {largest:g} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default="HEAD", help="the git revision to compare with (default HEAD)")
    parser.add_argument("--draw", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.draw is not None:
        draw(args.draw)
        return
    with tempfile.TemporaryDirectory(prefix="compare-renders-") as tmp:
        tree, ours, theirs = Path(tmp) / "tree", Path(tmp) / "ours", Path(tmp) / "theirs"
        ours.mkdir()
        theirs.mkdir()
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), args.against], check=True)
        try:
            env = {**os.environ, "LP_NUM_THREADS": "1"}
            me = str(Path(__file__).resolve())
            subprocess.run([sys.executable, me, "--draw", str(ours)], check=True, env={**env, "PYTHONPATH": str(ROOT)})
            subprocess.run(
                [sys.executable, me, "--draw", str(theirs)], check=True, env={**env, "PYTHONPATH": str(tree)}
            )
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=True)
        print(f"this tree against {args.against}, the robot's six cameras at {SIZE[0]}x{SIZE[1]}:")
        print("\n".join(compare(ours, theirs)))


if __name__ == "__main__":
    main()
