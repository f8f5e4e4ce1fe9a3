"""The ray engine (simbot/sim/physics/ray_scene.py) against the true surfaces and against PyBullet's
cast, in real PyBullet worlds, and its edges: a static model moved or removed, a robot blind to
itself, a mesh it cannot read, and the fallback to PyBullet's cast.

Tolerances are the issue's: a range within 1 cm (the lidar's resolution) on ≥ 99.5 % of rays, and
hit or no hit the same on ≥ 99.9 % of rays. The engine's curves lie within SAG_M/2 of the true
surface; PyBullet's cylinders are 32-sided hulls (up to 8 mm inside) and its capsules and spheres up
to a millimetre outside (an iterative convex cast), so a ray that grazes a curve within a
millimetre may hit in one cast and not the other: those are the 0.1 %.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import REPO
from gz_examples import gazebo_example

from simbot.description.sdf_reader import load_world
from simbot.sim.physics import Physics, embree
from simbot.sim.physics.ray_shapes import SAG_M
from simbot.sim.physics.rays import RAYS_VARIABLE, embree_installed
from simbot.transform import Transform

RESOLUTION_M = 0.01
IN_RANGE, AGREE = 0.995, 0.999
Floats = npt.NDArray[np.float64]

SHAPES = """<?xml version="1.0"?><sdf version="1.9"><world name="shapes"><gravity>0 0 0</gravity>
  <model name="box"><static>true</static><pose>3 0 0.5 0 0 0.3</pose><link name="l"><collision name="c">
    <geometry><box><size>1 0.6 1</size></box></geometry></collision></link></model>
  <model name="drum"><static>true</static><pose>0 3 0.5 0 0 0</pose><link name="l"><collision name="c">
    <geometry><cylinder><radius>0.4</radius><length>1</length></cylinder></geometry></collision></link></model>
  <model name="ball"><pose>-3 0 0.5 0 0 0</pose><link name="l"><inertial><mass>1</mass></inertial>
    <collision name="c"><geometry><sphere><radius>0.35</radius></sphere></geometry></collision></link></model>
  {extra}
</world></sdf>"""
"""A static box turned 0.3 rad, a static upright cylinder and a free sphere (gravity off), around the origin."""


def _physics(tmp_path: Path, text: str) -> Physics:
    path = tmp_path / "world.sdf"
    path.write_text(text)
    return _loaded(path)


def _loaded(path: Path) -> Physics:
    """Every model of the world at `path` in PyBullet, stepped once: PyBullet's own cast sees a
    body where it was loaded only after a step has brought its broadphase up to date."""
    world = load_world(path)
    physics = Physics(world)
    for model in world.models:
        physics.add_model(model)
    physics.step()
    return physics


@pytest.fixture
def shapes(tmp_path: Path) -> Iterator[Physics]:
    physics = _physics(tmp_path, SHAPES.format(extra=""))
    yield physics
    physics.close()


def fan(origin: tuple[float, float, float], rays: int = 3600, reach: float = 10.0) -> tuple[Floats, Floats]:
    """A planar fan all round `origin`, with a tilt that varies from ray to ray (±0.3 rad)."""
    azimuth = np.linspace(-math.pi, math.pi, rays, endpoint=False)
    tilt = 0.3 * np.sin(azimuth * 7.0)
    directions = np.stack([np.cos(tilt) * np.cos(azimuth), np.cos(tilt) * np.sin(azimuth), np.sin(tilt)], axis=1)
    starts = np.tile(origin, (rays, 1))
    return starts, starts + reach * directions


def analytic(starts: Floats, ends: Floats) -> Floats:
    """The first hit on SHAPES' true surfaces (m), +inf for none: slabs, a finite cylinder, a sphere."""
    span = ends - starts
    length = np.linalg.norm(span, axis=1)
    u = span / length[:, None]
    best = np.full(len(starts), np.inf)
    best = np.fmin(best, _box(starts, u, (3.0, 0.0, 0.5), 0.3, (0.5, 0.3, 0.5)))
    best = np.fmin(best, _cylinder(starts, u, (0.0, 3.0, 0.5), 0.4, 0.5))
    best = np.fmin(best, _sphere(starts, u, (-3.0, 0.0, 0.5), 0.35))
    return np.where(best <= length, best, np.inf)


def _box(o: Floats, u: Floats, centre: tuple[float, ...], yaw: float, half: tuple[float, ...]) -> Floats:
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world into the box's frame
    lo, lu = (o - centre) @ turn.T, u @ turn.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-np.asarray(half) - lo) / lu, (np.asarray(half) - lo) / lu
    near, far = np.nanmax(np.minimum(t1, t2), axis=1), np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((near <= far) & (near >= 0.0), near, np.inf)


def _cylinder(o: Floats, u: Floats, centre: tuple[float, ...], radius: float, half: float) -> Floats:
    p = o - centre
    a = u[:, 0] ** 2 + u[:, 1] ** 2
    b = 2 * (p[:, 0] * u[:, 0] + p[:, 1] * u[:, 1])
    disc = b * b - 4 * a * (p[:, 0] ** 2 + p[:, 1] ** 2 - radius**2)
    side = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * np.maximum(a, 1e-12)), np.inf)
    side = np.where((side >= 0) & (np.abs(p[:, 2] + np.nan_to_num(side, posinf=0.0) * u[:, 2]) <= half), side, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        caps = np.fmin(*((np.sign(z) * half - p[:, 2]) / u[:, 2] for z in (-1.0, 1.0)))
    at = p[:, :2] + np.nan_to_num(caps, posinf=0.0, neginf=0.0)[:, None] * u[:, :2]
    caps = np.where((caps >= 0) & (np.hypot(at[:, 0], at[:, 1]) <= radius), caps, np.inf)
    return np.fmin(side, caps)


def _sphere(o: Floats, u: Floats, centre: tuple[float, ...], radius: float) -> Floats:
    p = o - centre
    b = np.einsum("ij,ij->i", p, u)
    disc = b * b - (np.einsum("ij,ij->i", p, p) - radius**2)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc >= 0) & (t >= 0), t, np.inf)


def ranges(physics: Physics, starts: Floats, ends: Floats, engine: bool = True, blind: str | None = None) -> Floats:
    fractions = physics.cast_ray_batches([(starts, ends, blind)], engine=engine)[0]
    return np.where(np.isnan(fractions), np.inf, fractions * np.linalg.norm(ends - starts, axis=1))


def agreement(got: Floats, want: Floats) -> tuple[float, float]:
    """(share of rays that agree on hit or not, share of rays hit by both within RESOLUTION_M)."""
    hit_got, hit_want = np.isfinite(got), np.isfinite(want)
    both = hit_got & hit_want
    return float(np.mean(hit_got == hit_want)), float(np.mean(np.abs(got[both] - want[both]) <= RESOLUTION_M))


def test_ranges_are_the_true_surfaces_of_a_box_a_cylinder_and_a_sphere(shapes: Physics) -> None:
    """From three points, 3600 rays each, the engine reads the analytic ranges, 99 % of them within
    a millimetre (its facets lie within SAG_M/2 of the surface, met obliquely). PyBullet's cast, with its 32-sided
    cylinder, has 99.2 % within 1 cm from (-1, -1, 0.9), where rays graze the cylinder."""
    for origin in ((0.0, 0.0, 0.5), (1.0, 1.5, 0.2), (-1.0, -1.0, 0.9)):
        starts, ends = fan(origin)
        want, got = analytic(starts, ends), ranges(shapes, starts, ends)
        hits, within = agreement(got, want)
        assert hits >= AGREE and within >= IN_RANGE, (origin, hits, within)
        both = np.isfinite(got) & np.isfinite(want)
        assert np.percentile(np.abs(got[both] - want[both]), 99) < 4 * SAG_M


def test_a_moved_static_model_is_seen_where_it_went_and_a_removed_one_not_at_all(shapes: Physics) -> None:
    """set_pose on a static model and remove: the static structure follows each edit."""
    start, ahead, aside = np.array([[0.0, 0.0, 0.5]]), np.array([[10.0, 0.0, 0.5]]), np.array([[0.0, -10.0, 0.5]])
    shapes.set_model_pose("box", Transform((0.0, -3.0, 0.5), (0.0, 0.0, 0.0, 1.0)))
    assert np.isinf(ranges(shapes, start, ahead)[0])  # where the box stood
    assert ranges(shapes, start, aside)[0] == pytest.approx(2.7, abs=1e-3)  # where it went, square to the axes
    shapes.remove_model("box")
    assert np.isinf(ranges(shapes, start, aside)[0])
    starts, ends = fan((0.0, 0.0, 0.5))
    assert agreement(ranges(shapes, starts, ends), ranges(shapes, starts, ends, engine=False)) >= (AGREE, IN_RANGE)


def test_a_moving_body_is_seen_where_the_physics_holds_it_and_not_by_itself(shapes: Physics) -> None:
    """The free sphere, moved: cast where it is now; rays blind to it pass through to what lies behind."""
    shapes.set_model_pose("ball", Transform((2.0, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0)))
    start, end = np.array([[0.0, 0.0, 0.5]]), np.array([[10.0, 0.0, 0.5]])
    assert ranges(shapes, start, end)[0] == pytest.approx(1.65, abs=1e-3)
    behind = ranges(shapes, start, end, blind="ball")[0]  # through the ball, onto the box turned 0.3 rad
    assert behind == pytest.approx(ranges(shapes, start, end, engine=False, blind="ball")[0], abs=RESOLUTION_M)
    assert behind > 2.4


def test_a_mesh_that_cannot_be_read_is_one_line_and_the_rest_is_seen(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A model with a broken mesh beside a box in one link: one warning naming model, link and file;
    the box is still cast against."""
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid nothing\nendsolid nothing\n")
    extra = (
        '<model name="crate"><static>true</static><pose>0 -3 0.5 0 0 0</pose><link name="side">'
        f'<collision name="m"><geometry><mesh><uri>{broken}</uri></mesh></geometry></collision>'
        '<collision name="b"><geometry><box><size>1 1 1</size></box></geometry></collision></link></model>'
    )
    with caplog.at_level(logging.WARNING, logger="simbot.sim.physics.ray_shapes"):
        physics = _physics(tmp_path, SHAPES.format(extra=extra))
    try:
        lines = [r.getMessage() for r in caplog.records if r.name == "simbot.sim.physics.ray_shapes"]
        assert len(lines) == 1 and "'crate'" in lines[0] and "'side'" in lines[0] and "broken.stl" in lines[0], lines
        seen = ranges(physics, np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, -10.0, 0.5]]))
        assert seen[0] == pytest.approx(2.5, abs=1e-3)
    finally:
        physics.close()


@pytest.mark.parametrize("packets", [1, 3, 7])
def test_packets_lie_on_the_64_byte_boundary_avx512_loads_need(packets: int) -> None:
    """Embree loads a packet's rays and its valid flags with aligned vector loads: on an AVX-512
    CPU a misaligned buffer is a segmentation fault (AVX2 hid it). Every packet and flag row aligns."""
    buffer = embree._packets(packets)
    base, valid = buffer.rays.ctypes.data, buffer.valid(packets * embree.LANES - 1)
    rows = [base + k * buffer.rays.strides[0] for k in range(packets)]
    flags = [valid + k * embree.LANES * 4 for k in range(packets)]
    assert [address % 64 for address in rows + flags] == [0] * (2 * packets)


def test_without_the_engine_pybullet_casts_and_says_nothing_is_missing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIMBOT_RAYS=pybullet: no engine, PyBullet's rayTestBatch; the same ranges as the engine's."""
    monkeypatch.setenv(RAYS_VARIABLE, "pybullet")
    fallback = _physics(tmp_path, SHAPES.format(extra=""))
    monkeypatch.delenv(RAYS_VARIABLE)
    engine = _physics(tmp_path, SHAPES.format(extra=""))
    try:
        assert fallback._rays.scene is None and engine._rays.scene is not None
        starts, ends = fan((0.0, 0.0, 0.5))
        assert agreement(ranges(engine, starts, ends), ranges(fallback, starts, ends)) >= (AGREE, IN_RANGE)
    finally:
        fallback.close()
        engine.close()


def test_where_embree_is_missing_pybullet_casts_and_one_line_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """No Embree library (as on Linux aarch64, where embreex has no wheel): two worlds cast through
    PyBullet, the ranges the true surfaces', and one logged line in all names what is missing."""
    monkeypatch.setattr(embree, "library", lambda: None)
    embree_installed.cache_clear()
    try:
        with caplog.at_level(logging.WARNING, logger="simbot.sim.physics.rays"):
            worlds = [_physics(tmp_path, SHAPES.format(extra="")) for _ in range(2)]
        lines = [r.getMessage() for r in caplog.records if r.name == "simbot.sim.physics.rays"]
        assert len(lines) == 1 and "embreex" in lines[0], lines
        assert all(world._rays.scene is None for world in worlds)
        starts, ends = fan((0.0, 0.0, 0.5))
        assert agreement(ranges(worlds[0], starts, ends), analytic(starts, ends)) >= (AGREE, 0.99)
        for world in worlds:
            world.close()
    finally:
        embree_installed.cache_clear()


def _compared(physics: Physics, origins: list[tuple[float, float, float]]) -> tuple[float, float]:
    """The two casts' agreement over fans from `origins`."""
    got, want = [], []
    for origin in origins:
        starts, ends = fan(origin, 2000)
        got.append(ranges(physics, starts, ends))
        want.append(ranges(physics, starts, ends, engine=False))
    return agreement(np.concatenate(got), np.concatenate(want))


WORLDS = [
    REPO / "tests" / "fixtures" / "labelled" / "room.sdf",
    REPO / "tests" / "fixtures" / "lidar_boxes.sdf",
    REPO / "tests" / "fixtures" / "scene_room.sdf",
    REPO / "tests" / "fixtures" / "gazebo" / "shapes.sdf",
    REPO / "tests" / "fixtures" / "gazebo" / "heightmap.sdf",
    REPO / "worlds" / "warehouse.sdf",
]


@pytest.mark.parametrize("path", WORLDS, ids=[p.stem for p in WORLDS])
def test_the_engine_reads_what_pybullet_reads_in_the_test_rooms(path: Path) -> None:
    physics = _loaded(path)
    try:
        assert _compared(physics, [(0.7, -1.3, 0.4), (1.5, -1.0, 1.0), (-2.0, 2.0, 0.25)]) >= (AGREE, IN_RANGE)
    finally:
        physics.close()


@pytest.mark.parametrize("name", ["segmentation_camera.sdf", "boundingbox_camera.sdf", "thermal_camera.sdf"])
def test_the_engine_reads_what_pybullet_reads_in_gazebos_example_worlds(tmp_path: Path, name: str) -> None:
    physics = _loaded(gazebo_example(name, tmp_path))
    try:
        assert _compared(physics, [(0.0, 0.0, 0.5), (2.0, 1.0, 1.0)]) >= (AGREE, IN_RANGE)
    finally:
        physics.close()


def test_the_engine_reads_what_pybullet_reads_in_the_warehouse_with_people_walking() -> None:
    """Navigate-v0 in the warehouse with its people: every 10th of 200 env steps, both lidars' rays
    and a fan from the robot, each cast both ways, as the people, the cart and the robot move."""
    gymnasium = pytest.importorskip("gymnasium")
    import simbot.gym  # noqa: F401  registers the environments

    env = gymnasium.make("simbot/Navigate-v0", world="warehouse", people=True, physics="kinematic")
    try:
        env.reset(seed=3)
        physics = env.unwrapped.session.sim_world.physics
        got, want = [], []
        for step in range(200):
            env.step(np.array([0.4, 0.3 * math.sin(step / 20)], np.float32))
            if step % 10 == 0:
                position = physics.model_pose("flexley_tug").position
                starts, ends = fan((position[0], position[1], 0.35), 1440)
                got.append(ranges(physics, starts, ends, blind="flexley_tug"))
                want.append(ranges(physics, starts, ends, engine=False, blind="flexley_tug"))
        assert agreement(np.concatenate(got), np.concatenate(want)) >= (AGREE, IN_RANGE)
    finally:
        env.close()


def test_a_fleet_of_tugs_each_blind_to_itself_reads_what_pybullet_reads(tmp_path: Path) -> None:
    """Forty tugs (two hundred moving parts, the shapes of one tug shared) in rows clear of the test
    room's boxes, a fan from inside each tug blind to it, all forty in one cast: each ray passes
    through its own tug's parts (cast again from beyond each hit) and sees every other tug, as
    PyBullet's collision groups have it. (Clear of the boxes: a ray that starts inside another body
    sees its inside in the engine and not in PyBullet, docs/sensors.md.)"""
    from simbot.description.poses import Pose
    from simbot.description.sdf_reader import load_model

    physics = _loaded(REPO / "tests" / "fixtures" / "lidar_boxes.sdf")
    try:
        tug = load_model(REPO / "urdf" / "flexley_tug.sdf")
        names = [f"tug_{k}" for k in range(40)]
        for k, name in enumerate(names):
            row = (-10.5, -7.5, -4.5, 8.5, 11.5)[k // 8]
            physics.add_model(tug, name, Pose((-12.0 + 3.0 * (k % 8), row, 0.1), (0.0, 0.0, 0.4 * k)))
        physics.step()
        batches = [(*fan((*physics.model_pose(name).position[:2], 0.35), 720), name) for name in names]
        engine = physics.cast_ray_batches(batches)
        bullet = physics.cast_ray_batches(batches, engine=False)
        length = np.linalg.norm(batches[0][1] - batches[0][0], axis=1)
        got, want = (
            np.concatenate([np.where(np.isnan(f), np.inf, f * length) for f in casts]) for casts in (engine, bullet)
        )
        assert agreement(got, want) >= (AGREE, IN_RANGE)
        assert np.mean(np.isfinite(got) & (got < 3.0)) > 0.2  # the neighbours are seen, not only the room
    finally:
        physics.close()
