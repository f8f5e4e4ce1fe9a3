"""An animated worker's legs as the lidar sees them: a capsule per thigh and shin posed from the
skeleton each step by the actors system (real PyBullet, rays cast as the lidars cast them), against
the legs the skeleton itself gives at the rays' height, 0.22 m (shin height; the tug's lidars sweep 0.356 m up)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from simbot.description.actor_legs import CLIP_TIME, ActorRig
from simbot.description.sdf_reader import load_world
from simbot.description.skeleton_poses import ClipFile, load_rig
from simbot.sim.loop.system import ModelEvent, UpdateInfo
from simbot.sim.physics import Physics
from simbot.sim.systems.actors import LEGS_PERIOD_NS, Actors

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "worlds" / "models" / "worker" / "meshes"
LIDAR_Z, RANGE_M, RAYS, FAN_RAD = 0.22, 3.0, 721, 0.8
ACTOR_Z = 1.0
"""The worker's frame above the floor (its pelvis: the skin's origin)."""
CYCLE_S = 1.1
"""The walk cycle make_worker.py writes."""
TOUCH_M = FAN_RAD / (RAYS - 1) * RANGE_M * 2
"""Legs closer than this apart may show as one run or two (a ray or two between them)."""
CAST_M = 2.5e-3
"""How far the cast's edge of a leg may lie off the skeleton's, beyond a ray spacing: Bullet's ray
cast at a tilted capsule (an iterative convex cast, not a closed form) finds its surface up to about
a millimetre outside it (0.94 mm measured on a capsule tilted 0.5 rad, a shin's tilt at double
support; exact on an upright one), which hid that the capsules cut the plane up to 2 mm inside the
skeleton's bone cylinders at mid-swing; the ray engine's facets lie within 0.13 mm of the capsule
and show it (measured: its edges up to 1.9 mm further in than the ray spacing allows)."""
Run = tuple[float, float]


@pytest.fixture(scope="module")
def rig() -> ActorRig:
    return ActorRig.of(load_rig(MESHES / "worker.dae", (ClipFile(MESHES / "walk.dae", True),)), 1.0)


@contextmanager
def worker(tmp_path: Path) -> Iterator[Physics]:
    """The worker alone, its frame at (0, 0, ACTOR_Z), in real PyBullet."""
    world_file = tmp_path / "one.sdf"
    world_file.write_text(
        '<?xml version="1.0"?><sdf version="1.9"><world name="w"><include>'
        f"<uri>{REPO / 'worlds' / 'models' / 'worker' / 'model.sdf'}</uri><name>bob</name>"
        f"<pose>0 0 {ACTOR_Z} 0 0 0</pose></include></world></sdf>"
    )
    world = load_world(world_file)
    physics = Physics(world)
    try:
        physics.add_model(world.models[0])
        yield physics
    finally:
        physics.close()


def returns(physics: Physics, x: float) -> list[Run]:
    """(start, end) along x, from `x`, of each run of returns of a fan of rays cast across the walk
    from 3 m to the actor's right at LIDAR_Z, shin height."""
    angles = np.linspace(-FAN_RAD / 2, FAN_RAD / 2, RAYS)
    starts = np.tile([x, -RANGE_M, LIDAR_Z], (RAYS, 1))
    ends = starts + np.stack([6 * np.sin(angles), 6 * np.cos(angles), np.zeros(RAYS)], axis=1)
    fraction = physics.cast_rays(starts, ends)
    hit = ~np.isnan(fraction)
    xs = (starts + np.nan_to_num(fraction)[:, None] * (ends - starts))[:, 0] - x
    edges = np.flatnonzero(np.diff(np.concatenate([[0], hit.astype(np.int8), [0]])))
    return [(float(xs[a]), float(xs[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def skeleton_legs(rig: ActorRig, time: float) -> list[Run] | None:
    """Where the skeleton's legs cut the lidar's plane at `time` into the walk, left to right along x:
    each bone a cylinder of the legs' radius, so its cut an ellipse r / cos(tilt) either side of
    the bone's axis along the walk; legs that overlap are one run. None where the plane passes
    within r·tan(tilt) of a bone's end (where the capsule's round end cuts the ellipse short)."""
    pose = rig.rig.pose(0, time)
    plane = LIDAR_Z - ACTOR_Z
    radius = rig.leg_radius()
    runs = []
    for leg in rig.legs:
        for top, bottom in ((leg.thigh, leg.shin), (leg.shin, leg.foot)):
            a, b = pose[top, :3, 3], pose[bottom, :3, 3]
            if not min(a[2], b[2]) - radius <= plane <= max(a[2], b[2]) + radius:
                continue  # the capsule is clear of the plane
            length, rise = float(np.linalg.norm(b - a)), abs(float(b[2] - a[2]))
            along = (plane - a[2]) / (b[2] - a[2]) if rise > 0.0 else -1.0
            reach = radius * math.sqrt(max(length * length - rise * rise, 0.0)) / max(rise, 1e-9)  # r·tan(tilt)
            if min(along, 1.0 - along) * length < reach:
                return None
            centre = float(a[0] + along * (b[0] - a[0]))
            half = radius * length / rise
            runs.append((centre - half, centre + half))
    merged: list[Run] = []
    for start, end in sorted(runs):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return merged


def inside_m(edge: float, half: float) -> float:
    """How far inside a leg's edge (`edge` along the walk from the fan's source, `half` the cut's
    half-width) the run of returns may end: the last ray that hits is up to a ray spacing in, and
    a ray at φ off the perpendicular grazes the cut short of its widest point by at most
    half·(1 − cos φ)."""
    oblique = math.atan2(abs(edge), RANGE_M)
    return FAN_RAD / (RAYS - 1) * RANGE_M / math.cos(oblique) ** 2 + half * (1.0 - math.cos(oblique))


def assert_seen_as(seen: list[Run], expected: list[Run]) -> None:
    """The lidar's runs are the skeleton's: each edge up to `inside_m` inside, CAST_M outside."""
    assert len(seen) == len(expected), (seen, expected)
    for (start, end), (low, high) in zip(seen, expected, strict=True):
        half = (high - low) / 2
        assert low - CAST_M <= start <= low + inside_m(low, half) + CAST_M, (seen, expected)
        assert high - inside_m(high, half) - CAST_M <= end <= high + CAST_M, (seen, expected)


def test_at_double_support_the_lidar_sees_two_legs_at_the_widths_and_spacing_of_the_skeleton(
    tmp_path: Path, rig: ActorRig
) -> None:
    """Both feet down, a stride apart: two returns, each a shin's width (tilted, so wider than
    the leg), as far apart as the skeleton's shins at 0.22 m."""
    expected = skeleton_legs(rig, 0.0)
    assert expected is not None and len(expected) == 2 and expected[1][0] - expected[0][1] > 0.3  # well apart
    with worker(tmp_path) as physics:
        physics.set_joint_positions("bob", rig.positions(0, 0.0))
        physics.step()
        assert_seen_as(returns(physics, 0.0), expected)


@contextmanager
def walked(tmp_path: Path) -> Iterator[tuple[Physics, Iterator[int]]]:
    """The worker walked by the actors system at 1 ms steps: the physics, and the steps one by one
    (each yielded after the physics has stepped)."""
    with worker(tmp_path) as physics:
        actors = Actors(SimpleNamespace(physics=physics))  # type: ignore[arg-type]
        actors.model_added(ModelEvent("bob", ("bob",), ()))

        def steps() -> Iterator[int]:
            for k in range(1, 2200):  # from 0.5 s the worker walks at 1 m/s
                actors.pre_update(UpdateInfo(k * 1_000_000, 1_000_000, 1))
                physics.step()
                yield k

        yield physics, steps()


def test_the_legs_are_posed_every_10_ms_of_sim_time_and_hold_their_pose_between(tmp_path: Path) -> None:
    """The clip's time (and with it every leg joint) changes at the first step and at each multiple
    of LEGS_PERIOD_NS, never between: a 10 Hz lidar's every tick reads legs posed for its instant."""
    assert LEGS_PERIOD_NS == 10_000_000
    changed = []
    with walked(tmp_path) as (physics, steps):
        last = physics.body_state("bob")[1]  # as it entered, at time zero
        for k in steps:
            joints = physics.body_state("bob")[1]
            if joints != last:
                changed.append(k)
            last = joints
            if k == 300:
                break
    assert changed == [1, *range(10, 301, 10)], changed


def test_a_walking_workers_legs_cross_and_part_over_a_gait_cycle(tmp_path: Path, rig: ActorRig) -> None:
    """Walked by the actors system for a cycle and a half at 1 m/s: at every sample (every 20 ms, a
    step at which the legs are posed, so the lidar, the frame and the legs agree on the instant)
    the lidar sees the legs where the skeleton has them at the clip's time they were posed for; some
    samples show one run (the legs crossing) and some two (parted)."""
    counts = []
    with walked(tmp_path) as (physics, steps):
        for k in steps:
            if k % 20 == 0 and k > 500:  # a posing step (LEGS_PERIOD_NS 10 ms)
                base, joints = physics.body_state("bob")
                expected = skeleton_legs(rig, joints[CLIP_TIME])
                gaps = [] if expected is None else [b[0] - a[1] for a, b in zip(expected, expected[1:], strict=False)]
                if expected is not None and all(gap > 2 * TOUCH_M for gap in gaps):  # not as they touch
                    assert_seen_as(returns(physics, base.position[0]), expected)
                    counts.append(len(expected))
    assert 1 in counts and 2 in counts, counts
