"""BVH animations on a COLLADA skin's skeleton, as gz-common's BVHLoader reads them
(simbot/description/bvh_clips.py): the worker's skin (worlds/models/worker/meshes/worker.dae)
driven by small BVH files written here; and the units of animations and skins, BVH's `<scale>`
and COLLADA's `<unit meter>`."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest

from simbot.description.actor_scripts import ActorModel, SkinnedMesh
from simbot.description.bvh_clips import read_bvh_clip
from simbot.description.sdf_reader import load_world
from simbot.description.skeleton_poses import ClipFile, global_pose, load_rig
from simbot.description.skeletons import Skeleton, SkeletonError, read_clip, read_skeleton

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "worlds" / "models" / "worker" / "meshes"
SKIN = MESHES / "worker.dae"
FRAME_TIME = 0.25

HIERARCHY = """HIERARCHY
ROOT pelvis
{
  OFFSET 5 3 7
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT thigh_l
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 0 -46
    }
  }
}
"""
FRAMES = ["0 0 100 0 0 0 0 0 0", "50 0 100 0 0 0 30 0 0", "100 20 100 0 0 0 90 90 0"]
"""pelvis x, y, z (cm), its Z, X, Y turns; thigh_l's Z, X, Y turns (degrees)."""
ONE_FRAME = f"MOTION\nFrames: 1\nFrame Time: 0.1\n{FRAMES[0]}\n"


@pytest.fixture(scope="module")
def skeleton() -> Skeleton:
    return read_skeleton(SKIN)


def _bvh(tmp_path: Path, hierarchy: str = HIERARCHY, frames: list[str] = FRAMES, name: str = "walk.bvh") -> Path:
    path = tmp_path / name
    motion = f"MOTION\nFrames: {len(frames)}\nFrame Time: {FRAME_TIME}\n" + "\n".join(frames) + "\n"
    path.write_text(hierarchy + motion)
    return path


def _turn(axis: int, degrees: float) -> np.ndarray:
    """A right-handed rotation about x, y or z (Rodrigues' formula of the unit axis)."""
    k = np.zeros((3, 3))
    a, b = (axis + 1) % 3, (axis + 2) % 3
    k[b, a], k[a, b] = 1.0, -1.0
    angle = math.radians(degrees)
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def test_a_joints_turn_at_a_frame_is_its_local_rotation(tmp_path: Path, skeleton: Skeleton) -> None:
    """Frame 1 turns thigh_l 30° about z: its local rotation is that turn, within 1e-9, keyed at
    1 · Frame Time."""
    clip = read_bvh_clip(_bvh(tmp_path), skeleton)
    np.testing.assert_allclose(clip.times, np.arange(3) * FRAME_TIME, rtol=0, atol=1e-12)
    thigh = skeleton.index("thigh_l")
    np.testing.assert_allclose(clip.locals[1, thigh, :3, :3], _turn(2, 30.0), atol=1e-9)
    np.testing.assert_allclose(clip.locals[0, thigh, :3, :3], np.eye(3), atol=1e-12)


def test_rotations_compose_in_the_order_of_their_channels(tmp_path: Path, skeleton: Skeleton) -> None:
    """`Zrotation 90 Xrotation 90`: Rz·Rx, so the thigh's y axis goes to z (X turns it up first,
    then Z leaves it), not to −x (as Rx·Rz would)."""
    clip = read_bvh_clip(_bvh(tmp_path), skeleton)
    rotation = clip.locals[2, skeleton.index("thigh_l"), :3, :3]
    np.testing.assert_allclose(rotation, _turn(2, 90.0) @ _turn(0, 90.0), atol=1e-9)
    np.testing.assert_allclose(rotation @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-9)


def test_the_scale_multiplies_offsets_and_position_channels(tmp_path: Path, skeleton: Skeleton) -> None:
    """`<scale>` 0.01 (the BVH in centimetres): the pelvis 1 m up and 0.5 m along x at frame 1,
    the thigh 0.1 m to the left of it; the position channels replace the root's OFFSET (5, 3, 7)."""
    clip = read_bvh_clip(_bvh(tmp_path), skeleton, 0.01)
    pelvis, thigh = skeleton.index("pelvis"), skeleton.index("thigh_l")
    np.testing.assert_allclose(clip.locals[1, pelvis, :3, 3], [0.5, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(clip.locals[2, pelvis, :3, 3], [1.0, 0.2, 1.0], atol=1e-12)
    np.testing.assert_allclose(clip.locals[:, thigh, :3, 3], [[0.0, 0.1, 0.0]] * 3, atol=1e-12)
    assert clip.x_displacement == pytest.approx(1.0, abs=1e-12)


def test_skin_joints_the_bvh_lacks_keep_their_rest_transform(tmp_path: Path, skeleton: Skeleton) -> None:
    """Neither the skin's joints the BVH names nor the `<scale>` move the others: bit for bit."""
    clip = read_bvh_clip(_bvh(tmp_path), skeleton, 0.01)
    for name in ("spine", "shin_l", "thigh_r", "foot_r"):
        joint = skeleton.index(name)
        for k in range(len(clip.times)):
            assert np.array_equal(clip.locals[k, joint], skeleton.rest[joint]), (name, k)


def test_a_bvh_file_is_read_by_its_suffix(tmp_path: Path, skeleton: Skeleton) -> None:
    """load_rig reads `.BVH` (any case) as BVH, `<scale>` applied once, as a COLLADA clip beside it."""
    rig = load_rig(SKIN, (ClipFile(_bvh(tmp_path, name="walk.BVH"), True, 0.01),))
    expected = read_bvh_clip(_bvh(tmp_path), skeleton, 0.01)
    assert np.array_equal(rig.clips[0].locals, expected.locals)
    assert rig.clip_time(0, 0.0, 0.5) == pytest.approx(0.25)  # half the 1 m stride: half the 0.5 s clip


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("ROOT pelvis\n{\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n\n", "does not begin with HIERARCHY"),
        (HIERARCHY, "no MOTION"),
        (HIERARCHY.replace("OFFSET 0 10 0", "OFFSET 0 ten 0") + "MOTION\nFrames: 0\nFrame Time: 0.1\n", "'ten'"),
        (HIERARCHY + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 1 0 0 0 zero 0 0\n", "'zero' is not a number"),
        (HIERARCHY + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 1 0 0 0 0 0\n", "frame 0: 8 values"),
        (HIERARCHY.replace("thigh_l", "tail") + ONE_FRAME, "joint 'tail': the skin has no joint"),
        (HIERARCHY.replace("thigh_l", "shin_l") + ONE_FRAME, "its parent is 'pelvis', in the skin 'thigh_l'"),
        (HIERARCHY + "MOTION\nFrames: 0\nFrame Time: 0.1\n", "no frames"),
        (HIERARCHY + "MOTION\nFrames: 2\nFrame Time: 0.1\n" + FRAMES[0] + "\n", "Frames: 2, but 1 frame lines"),
        (HIERARCHY + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 1 0 0 0 nan 0 0\n", "'nan' is not a number"),
        (HIERARCHY.replace("OFFSET 0 10 0", "OFFSET 0 10") + ONE_FRAME, "OFFSET: 'CHANNELS' is not a number"),
        ("HIERARCHY\nROOT pelvis\n{\nOFFSET 0 10\n" + ONE_FRAME, "OFFSET 0 10: not 3 numbers"),
    ],
    ids=[
        "no-hierarchy",
        "no-motion",
        "bad-offset",
        "bad-value",
        "short-frame",
        "unknown-joint",
        "parent",
        "zero",
        "count",
        "not-finite",
        "short-offset",
        "cut-offset",
    ],
)
def test_bad_files_raise_saying_why(tmp_path: Path, skeleton: Skeleton, text: str, reason: str) -> None:
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(SkeletonError, match=reason):
        read_bvh_clip(path, skeleton)


def _world(tmp_path: Path, bvh: Path) -> Path:
    world = tmp_path / "w.sdf"
    world.write_text(
        '<?xml version="1.0"?><sdf version="1.9"><world name="w"><actor name="mocap">'
        f"<skin><filename>{SKIN}</filename></skin>"
        f'<animation name="walk"><filename>{bvh}</filename><scale>0.01</scale>'
        "<interpolate_x>true</interpolate_x></animation></actor></world></sdf>"
    )
    return world


def _skin(actor: ActorModel) -> SkinnedMesh:
    skins = [v.geometry for link in actor.links for v in link.visuals]
    assert len(skins) == 1 and isinstance(skins[0], SkinnedMesh)
    return skins[0]


def test_an_actor_with_a_bvh_animation_is_animated(tmp_path: Path) -> None:
    """An SDF `<actor>` whose `<animation>` is a BVH file: the skin plays it (the rig's clip is the
    BVH's, scaled, a frame every Frame Time), and its legs are the leg proxies."""
    actor = load_world(_world(tmp_path, _bvh(tmp_path))).models[0]
    assert isinstance(actor, ActorModel)
    skin = _skin(actor)
    assert skin.path == SKIN and len(skin.animations) == 1
    clip = load_rig(SKIN, skin.animations).clips[0]
    np.testing.assert_allclose(clip.times, [0.0, FRAME_TIME, 2 * FRAME_TIME], atol=1e-12)
    assert clip.x_displacement == pytest.approx(1.0, abs=1e-12)
    assert "proxy" not in [c.name for c in actor.link("body").collisions]


def test_a_bvh_naming_a_bone_the_skin_lacks_is_one_warning_and_the_actor_unanimated(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    bvh = _bvh(tmp_path, HIERARCHY.replace("thigh_l", "tail"))
    with caplog.at_level(logging.WARNING):
        actor = load_world(_world(tmp_path, bvh)).models[0]
    assert isinstance(actor, ActorModel)
    warnings = [r.getMessage() for r in caplog.records if "tail" in r.getMessage()]
    assert len(warnings) == 1 and "'mocap'" in warnings[0] and "<animation>" in warnings[0], warnings
    assert not _skin(actor).animations  # the bind pose
    assert [c.name for c in actor.link("body").collisions] == ["proxy"]


def test_a_collada_files_unit_scales_its_lengths(tmp_path: Path, skeleton: Skeleton) -> None:
    """`<unit meter="0.01">` (the worker and its walk in centimetres), as gz-common's ColladaLoader
    reads it: the skin's vertices, its joints' and bind translations and the clip's translations a
    hundredth, its rotations as they were; the bind pose still undoes its inverse bind matrices."""
    for name in ("worker.dae", "walk.dae"):
        (tmp_path / name).write_text((MESHES / name).read_text().replace('meter="1"', 'meter="0.01"'))
    small = read_skeleton(tmp_path / "worker.dae")
    np.testing.assert_allclose(small.rest[:, :3, 3], 0.01 * skeleton.rest[:, :3, 3], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(small.rest[:, :3, :3], skeleton.rest[:, :3, :3])
    for pose, inverse in zip(global_pose(small, small.rest), small.inverse_bind, strict=True):
        np.testing.assert_allclose(pose @ inverse, np.eye(4), atol=1e-12)
    for part, full in zip(small.parts, skeleton.parts, strict=True):
        np.testing.assert_allclose(part.positions, 0.01 * full.positions, rtol=1e-12, atol=1e-15)
    clip, walk = read_clip(tmp_path / "walk.dae", small), read_clip(MESHES / "walk.dae", skeleton)
    np.testing.assert_allclose(clip.locals[..., :3, 3], 0.01 * walk.locals[..., :3, 3], rtol=1e-12, atol=1e-15)
    assert clip.x_displacement == pytest.approx(0.01 * walk.x_displacement, rel=1e-12)


@pytest.mark.parametrize("meter", ["inch", "inf", "0"])
def test_a_collada_unit_that_is_not_a_length_raises(tmp_path: Path, meter: str) -> None:
    skin = tmp_path / "worker.dae"
    skin.write_text(SKIN.read_text().replace('meter="1"', f'meter="{meter}"'))
    with pytest.raises(SkeletonError, match=f"<unit meter='{meter}'>: not a positive number"):
        read_skeleton(skin)
