"""The kinematic tree of a generated URDF, read once: the tug's joints, the hosts its fixed links
merge into, and its castors written fixed under their own names."""

from __future__ import annotations

from conftest import ROBOT_SDF

from simbot.description import load_model, model_to_urdf
from simbot.description.kinematics import URDF_DEFAULT_AXIS, KinematicTree
from simbot.description.poses import Pose
from simbot.description.urdf_writer import model_to_urdf_held
from simbot.sim.physics import ball_castors

WHEELS = {"front_left_wheel_joint", "back_left_wheel_joint", "front_right_wheel_joint", "back_right_wheel_joint"}


def test_the_tugs_tree_moves_its_wheels_and_castor_gimbals() -> None:
    tree = KinematicTree.of_urdf(model_to_urdf(load_model(ROBOT_SDF)))
    moving = {joint.name for joint in tree.moving()}
    assert moving >= WHEELS and len(moving - WHEELS) == 12
    assert all(
        joint.part_of(ball_castors(load_model(ROBOT_SDF))) for joint in tree.moving() if joint.name not in WHEELS
    )
    assert {joint.child for joint in tree.joints} == set(tree.links) - {tree.links[0]}


def test_held_joints_are_written_fixed_and_merge_into_their_host() -> None:
    """The castors held: every URDF joint keeps its name, links and origin; the gimbals are fixed,
    so each castor's links merge into the chassis, as PyBullet merges them."""
    model = load_model(ROBOT_SDF)
    castors = ball_castors(model)
    written, lean = model_to_urdf_held(model, castors)
    assert written == model_to_urdf(model)
    tree, held = KinematicTree.of_urdf(written), KinematicTree.of_urdf(lean)
    assert [j.name for j in held.joints] == [j.name for j in tree.joints] and held.links == tree.links
    assert [j.origin for j in held.joints] == [j.origin for j in tree.joints]
    assert {joint.name for joint in held.moving()} == WHEELS
    gimbals = {joint.name for joint in tree.joints if joint.part_of(castors)}
    assert tree.fixed_hosts(gimbals) == held.fixed_hosts()
    assert {host for link, host in held.fixed_hosts().items() if link.startswith("castor_")} == {tree.links[0]}


def test_a_joint_without_origin_or_axis_reads_urdfs_defaults() -> None:
    urdf = """<robot name="r"><link name="a"/><link name="b"/>
      <joint name="j" type="revolute"><parent link="a"/><child link="b"/></joint></robot>"""
    (joint,) = KinematicTree.of_urdf(urdf).joints
    assert (joint.origin, joint.axis, joint.fixed) == (Pose(), URDF_DEFAULT_AXIS, False)
