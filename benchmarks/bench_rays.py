"""The ray engine against PyBullet's cast of the same rays, in the same run (docs/speed.md, "The ray engine").

1. one env step's rays: Navigate-v0 in the warehouse with its people, the two lidars' 1440 rays
   cast together, by the engine and by `rayTestBatch` (blind to the robot both ways);
2. a hundred tugs' lidars due together among the warehouse's racks: the 200 scans' rays in one
   cast by the engine, and by PyBullet (one `rayTestBatch` a lidar, as the fallback casts), per scan;
3. the static structure's build in the warehouse (what a world edit costs again), and the moving
   parts' scenes and instance array in the warehouse with its people (what a world's first cast
   costs for them; a body entering or leaving later builds only the array).

Each figure is the median of repeated timings on one core; the ratio is PyBullet's over the engine's.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from tables import cpu_model, publish

import simbot.gym  # noqa: F401  registers simbot/Navigate-v0
from simbot.description.lidar_params import LidarParams
from simbot.description.poses import Pose
from simbot.description.sdf_reader import load_model, load_world
from simbot.sim.physics import Physics
from simbot.sim.physics.protocols import RayBatch
from simbot.sim.systems.lidar import ray_fan
from simbot.transform import quaternion_to_matrix

REPO = Path(__file__).resolve().parents[1]
TUGS = 100
RAYS = 720


def median_s(call: Callable[[], Any], repeats: int) -> float:
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def env_step() -> tuple[float, float, float, int]:
    """(engine, PyBullet) seconds for one env step's two lidars' rays, warehouse with people; the
    seconds to build its moving parts' structure, and their triangles."""
    env = gymnasium.make("simbot/Navigate-v0", world="warehouse", people=True, physics="kinematic")
    try:
        env.reset(seed=0)
        for _ in range(20):
            env.step(np.array([0.3, 0.0], np.float32))
        physics = env.unwrapped.session.sim_world.physics  # type: ignore[attr-defined]
        batches = _lidar_batches(physics, ["flexley_tug"])
        scene = physics._rays.scene
        assert scene is not None, "the ray engine (embreex) is not installed"
        return (
            median_s(lambda: physics.cast_ray_batches(batches), 400),
            median_s(lambda: physics.cast_ray_batches(batches, engine=False), 100),
            median_s(scene.moving_build, 10),
            scene.moving_build(),
        )
    finally:
        env.close()


def _lidar_batches(physics: Physics, robots: list[str]) -> list[RayBatch]:
    """Each robot's two lidars' rays, from where they are now (as Lidar._rays casts them)."""
    tug = physics.model_of(robots[0])
    batches: list[RayBatch] = []
    lidars = [(link, sensor) for link in tug.links for sensor in link.sensors if sensor.type in ("gpu_lidar", "lidar")]
    for link, sensor in lidars:
        params = LidarParams.from_sdf(sensor)
        directions = ray_fan(params).directions.reshape(-1, 3)
        for robot in robots:
            position, quat = physics.frame_pose(robot, link.name, sensor.pose)
            turned = directions @ quaternion_to_matrix(quat).T
            origin = np.asarray(position)
            batches.append((origin + turned * params.range_min, origin + turned * params.range_max, robot))
    return batches


def fleet() -> tuple[float, float, int]:
    """(engine, PyBullet) seconds a scan for TUGS tugs' lidars cast together among the racks; scans."""
    world = load_world(REPO / "worlds" / "warehouse.sdf")
    physics = Physics(world)
    try:
        for model in world.models:
            physics.add_model(model)
        tug = load_model(REPO / "urdf" / "flexley_tug.sdf")
        names = []
        for k in range(TUGS):
            x, y = -8.0 + 1.6 * (k % 10) + 0.4, -8.0 + 1.6 * (k // 10) + 0.3
            names.append(f"tug_{k}")
            physics.add_model(tug, names[-1], Pose((x, y, 0.1), (0.0, 0.0, 0.7 * k)))
        physics.step()
        batches = _lidar_batches(physics, names)
        for name in names:
            physics.blind_rays_to(name)  # as each lidar's setup does
        engine = median_s(lambda: physics.cast_ray_batches(batches), 10)
        bullet = median_s(lambda: physics.cast_ray_batches(batches, engine=False), 3)
        return engine / len(batches), bullet / len(batches), len(batches)
    finally:
        physics.close()


def static_build() -> tuple[float, int]:
    """Seconds to build the warehouse's static structure, and its triangles."""
    world = load_world(REPO / "worlds" / "warehouse.sdf")
    physics = Physics(world)
    try:
        for model in world.models:
            physics.add_model(model)
        scene = physics._rays.scene
        assert scene is not None, "the ray engine (embreex) is not installed"
        triangles = scene.static_build()
        return median_s(scene.static_build, 20), triangles
    finally:
        physics.close()


def main() -> None:
    step_engine, step_bullet, moving, moving_triangles = env_step()
    scan_engine, scan_bullet, scans = fleet()
    build, triangles = static_build()
    cpu = cpu_model()
    publish(
        "rays",
        [
            f"| measurement ({cpu}, one core) | PyBullet's cast | the engine | ratio | goal |",
            "| --- | --- | --- | --- | --- |",
            f"| one env step's 1440 rays, warehouse with people | {step_bullet * 1e3:.2f} ms | "
            f"{step_engine * 1e3:.3f} ms | **{step_bullet / step_engine:.1f}×** | ≥ 20× (≤ 0.15 ms) |",
            f"| a scan's rays, {TUGS} tugs' {scans} lidars cast together among the racks | "
            f"{scan_bullet * 1e3:.2f} ms | {scan_engine * 1e3:.3f} ms | **{scan_bullet / scan_engine:.1f}×** | "
            "≤ 0.1 ms a scan all-in |",
            f"| the static structure's build, warehouse ({triangles} triangles) | — | {build * 1e3:.1f} ms | — | ≤ 50 ms |",
            f"| the moving parts' build, warehouse with people ({moving_triangles} triangles) | — | "
            f"{moving * 1e3:.1f} ms | — | — |",
        ],
    )


if __name__ == "__main__":
    main()
