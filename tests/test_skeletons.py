"""The worker's skeleton and walk cycle (meshes/make_worker.py) as simbot reads and plays them
(simbot/description/skeletons.py, skeleton_poses.py), and the cameras drawing the posed skin: a
real render worker with the GL renderer, the actor's joints set as the actors system sets them."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from simbot.description.actor_legs import ActorRig
from simbot.description.actor_scripts import ActorModel, SkinnedMesh
from simbot.description.sdf_reader import load_world
from simbot.description.skeleton_poses import ClipFile, global_pose, load_rig
from simbot.description.skeletons import read_skeleton
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.physics import Physics
from simbot.sim.render.pool import RenderPool
from simbot.sim.render.specs import Annotation, BodyState, CameraSpec
from simbot.sim.render.visuals import visual_points
from simbot.transform import Transform

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "worlds" / "models" / "worker" / "meshes"
CYCLE_S, STRIDE_M = 1.1, 1.4
"""The walk cycle make_worker.py writes."""


@pytest.fixture(scope="module")
def rig() -> ActorRig:
    return ActorRig.of(load_rig(MESHES / "worker.dae", (ClipFile(MESHES / "walk.dae", True),)), 1.0)


def test_the_skeleton_reads_its_joints_binds_and_weights() -> None:
    skeleton = read_skeleton(MESHES / "worker.dae")
    assert len(skeleton.names) == 13
    rest = global_pose(skeleton, skeleton.rest)
    for pose, inverse in zip(rest, skeleton.inverse_bind, strict=True):
        np.testing.assert_allclose(pose @ inverse, np.eye(4), atol=1e-9)
    for part in skeleton.parts:
        np.testing.assert_allclose(part.weights.sum(axis=1), 1.0, atol=1e-12)


def test_the_feet_are_a_quarter_stride_ahead_and_behind_at_double_support(rig: ActorRig) -> None:
    left, right = (rig.rig.skeleton.index(f"foot_{s}") for s in ("l", "r"))
    for time, sign in ((0.0, 1.0), (CYCLE_S / 2, -1.0)):
        pose = rig.rig.pose(0, time)
        assert pose[left, 0, 3] == pytest.approx(sign * STRIDE_M / 4, abs=0.01)
        assert pose[right, 0, 3] == pytest.approx(-sign * STRIDE_M / 4, abs=0.01)


def test_with_interpolate_x_a_stride_walked_is_one_cycle(rig: ActorRig) -> None:
    assert rig.rig.clip_time(0, 0.0, STRIDE_M / 2) == pytest.approx(CYCLE_S / 2)
    assert rig.rig.clip_time(0, 123.0, STRIDE_M) == pytest.approx(0.0, abs=1e-9)


def test_an_animation_naming_bones_the_skin_lacks_is_one_warning_and_the_actor_walks_unanimated(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    bad = (MESHES / "walk.dae").read_text().replace('target="thigh_l/', 'target="tail/')
    (tmp_path / "walk.dae").write_text(bad)
    model = (REPO / "worlds" / "models" / "worker" / "model.sdf").read_text()
    model = model.replace("model://worker/meshes/walk.dae", str(tmp_path / "walk.dae"))
    model = model.replace("model://worker/meshes/worker.dae", str(MESHES / "worker.dae"))
    world = tmp_path / "w.sdf"
    world.write_text(
        model.replace('<sdf version="1.9">', '<sdf version="1.9"><world name="w">').replace("</sdf>", "</world></sdf>")
    )
    with caplog.at_level(logging.WARNING):
        actor = load_world(world).models[0]
    assert isinstance(actor, ActorModel)
    warnings = [r.getMessage() for r in caplog.records if "tail" in r.getMessage()]
    assert len(warnings) == 1 and "'worker'" in warnings[0] and "<animation>" in warnings[0]
    skins = [v.geometry for link in actor.links for v in link.visuals]
    assert len(skins) == 1 and isinstance(skins[0], SkinnedMesh) and not skins[0].animations  # the bind pose
    assert [c.name for c in actor.link("body").collisions] == ["proxy"]


def _world(tmp_path: Path) -> Path:
    world = tmp_path / "one.sdf"
    world.write_text(
        '<?xml version="1.0"?><sdf version="1.9"><world name="w"><include>'
        f"<uri>{REPO / 'worlds' / 'models' / 'worker' / 'model.sdf'}</uri><name>bob</name>"
        "<pose>0 0 1 0 0 0</pose></include></world></sdf>"
    )
    return world


def test_a_camera_sees_the_legs_swing_and_the_labels_follow_them(tmp_path: Path, rig: ActorRig) -> None:
    """Seen from the side, 4 m away: at double support the legs are a stride apart (the person's label
    wider than at mid-stance by about half a stride in pixels)."""
    world = load_world(_world(tmp_path))
    physics = Physics(world)
    try:
        physics.add_model(world.models[0])
        body = scene_body(physics, "bob", (Annotation(label=7),), instance=1)
        base = physics.body_state("bob")[0]
        camera = CameraSpec("side", 160, 120, 1.0, 0.1, 20.0, outputs=("color", "labels"))
        pose = Transform((0.0, -4.0, 0.5), (0.0, 0.0, 0.7071068, 0.7071068))
        widths = []
        with RenderPool([body], [camera], workers=1, renderer="gl") as pool:
            for stamp, time in enumerate((0.0, CYCLE_S / 4)):
                pool.request(0, stamp, pose, {"bob": BodyState(base, rig.positions(0, time))})
                frame = pool.collect(wait_for=0, timeout=60)[0]
                legs = (np.asarray(frame["labels"]) >> 16 & 0xFF) == 7
                columns = np.flatnonzero(legs[50:].any(axis=0))  # below the hips
                widths.append(columns.max() - columns.min())
        focal = 80 / np.tan(0.5)
        below = 0.5 + (60 - 50) / focal * 4.0  # world z of image row 50, 4 m away
        skin = next(v.visual for v in body.visuals if isinstance(v.visual.geometry, SkinnedMesh))
        for time, width in zip((0.0, CYCLE_S / 4), widths, strict=True):
            points = visual_points(skin, rig.positions(0, time))
            legs_x = points[points[:, 2] + 1.0 < below, 0]
            expected = (legs_x.max() - legs_x.min()) * focal / 4.0
            assert width == pytest.approx(expected, abs=3.0), f"at {time} s"
        assert widths[0] > widths[1] + 0.2 * focal / 4.0  # the feet a stride apart, then together
    finally:
        physics.close()


def test_an_animations_scale_scales_its_stride() -> None:
    """`<animation><scale>` 2: the clip's translations doubled, as Gazebo scales an animation's
    skeleton, so with interpolate_x a cycle takes twice the distance."""
    scaled = load_rig(MESHES / "worker.dae", (ClipFile(MESHES / "walk.dae", True, 2.0),))
    assert scaled.clips[0].x_displacement == pytest.approx(2 * STRIDE_M, abs=1e-9)
    assert scaled.clip_time(0, 0.0, STRIDE_M) == pytest.approx(CYCLE_S / 2)


def test_tiny_renderer_draws_the_skin_in_its_bind_pose(tmp_path: Path) -> None:
    """PyBullet reads no skinned COLLADA: TinyRenderer draws the worker from its bind-pose stand-in
    (not its leg capsules), labelled, as tall in the image as the skin is."""
    world = load_world(_world(tmp_path))
    physics = Physics(world)
    try:
        physics.add_model(world.models[0])
        body = scene_body(physics, "bob", (Annotation(label=7),), instance=1)
        base, joints = physics.body_state("bob")
        camera = CameraSpec("side", 160, 120, 1.0, 0.1, 20.0, outputs=("color", "labels"))
        pose = Transform((0.0, -4.0, 0.9), (0.0, 0.0, 0.7071068, 0.7071068))
        with RenderPool([body], [camera], workers=1, renderer="tiny") as pool:
            pool.request(0, 0, pose, {"bob": BodyState(base, joints)})
            person = (np.asarray(pool.collect(wait_for=0, timeout=60)[0]["labels"]) >> 16 & 0xFF) == 7
    finally:
        physics.close()
    rows, columns = np.flatnonzero(person.any(axis=1)), np.flatnonzero(person.any(axis=0))
    focal = 80 / np.tan(0.5)
    points = np.concatenate([p.positions for p in read_skeleton(MESHES / "worker.dae").parts])
    tall, deep = np.ptp(points[:, 2]), np.ptp(points[:, 1]) / 2  # its ends are within `deep` of 4 m
    assert tall * focal / (4.0 + deep) - 2 <= rows.max() - rows.min() + 1 <= tall * focal / (4.0 - deep) + 2
    assert columns.max() - columns.min() < 0.6 * focal / 4.0  # its legs together: no stride apart
