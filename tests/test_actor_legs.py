"""An animated worker's legs as the lidar sees them: a capsule per thigh and shin posed from the
skeleton each step by the actors system (real PyBullet, rays cast as the lidars cast them)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from simbot.description.sdf_reader import load_world
from simbot.sim.loop.system import ModelEvent, UpdateInfo
from simbot.sim.physics import Physics
from simbot.sim.systems.actors import Actors

REPO = Path(__file__).resolve().parents[1]
LIDAR_Z, RANGE_M, RAYS = 0.22, 3.0, 721


def _clusters(physics: Physics, x: float) -> list[tuple[float, float]]:
    """(start, end) along x of each run of returns of a fan of rays from 3 m to the actor's side, at 0.22 m."""
    angles = np.linspace(-0.4, 0.4, RAYS)
    starts = np.tile([x, -RANGE_M, LIDAR_Z], (RAYS, 1))
    ends = starts + np.stack([6 * np.sin(angles), 6 * np.cos(angles), np.zeros(RAYS)], axis=1)
    fraction = physics.cast_rays(starts, ends)
    hit = ~np.isnan(fraction)
    xs = (starts + np.nan_to_num(fraction)[:, None] * (ends - starts))[:, 0] - x
    runs, start = [], None
    for i, h in enumerate(hit):
        if h and start is None:
            start = i
        if start is not None and (not h or i == RAYS - 1):
            runs.append((float(xs[start]), float(xs[i - 1 if not h else i])))
            start = None
    return runs


def test_the_lidar_sees_two_legs_that_cross_and_part(tmp_path: Path) -> None:
    world_file = tmp_path / "one.sdf"
    world_file.write_text(
        '<?xml version="1.0"?><sdf version="1.9"><world name="w"><include>'
        f"<uri>{REPO / 'worlds' / 'models' / 'worker' / 'model.sdf'}</uri><name>bob</name>"
        "<pose>0 0 1 0 0 0</pose></include></world></sdf>"
    )
    world = load_world(world_file)
    physics = Physics(world)
    try:
        physics.add_model(world.models[0])
        actors = Actors(SimpleNamespace(physics=physics))  # type: ignore[arg-type]
        actors.model_added(ModelEvent("bob", ("bob",), ()))
        counts, gaps = [], []
        for k in range(1, 1200):  # from 0.5 s the worker walks at 1 m/s: over a cycle and a half
            actors.pre_update(UpdateInfo(k * 1_000_000, 1_000_000, 1))
            physics.step()
            if k % 20 == 0 and k > 500:
                x = physics.model_pose("bob").position[0]
                runs = _clusters(physics, x)
                counts.append(len(runs))
                gaps.append(runs[1][0] - runs[0][1] if len(runs) == 2 else 0.0)
        assert 1 in counts and 2 in counts, counts  # the legs cross (one cluster) and part (two)
        assert max(gaps) > 0.3, gaps
    finally:
        physics.close()
