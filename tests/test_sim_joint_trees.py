"""A model whose links form several joint trees (Gazebo allows it; a URDF holds one tree): one
PyBullet body per tree, each falling on its own, the main one keeping the model's name and plugins."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import settled_physics

from simbot.description import DescriptionError, load_world, model_to_urdf
from simbot.description.model import Joint, Model
from simbot.description.urdf_writer import joint_trees
from simbot.sim.physics import Physics

WORLD = Path(__file__).parent / "fixtures" / "gazebo" / "two_trees.sdf"
SETTLE_STEPS = 2000
"""2 s at 1 ms: boxes dropped from 0.4 m and 0.9 m are at rest by then."""
CONTACT_SLOP = 1e-3
"""Bullet rests a box sunk by well under a millimetre."""


def pair() -> Model:
    return next(m for m in load_world(WORLD).models if m.name == "pair")


@pytest.fixture(scope="module")
def settled() -> Iterator[Physics]:
    yield from settled_physics(WORLD, SETTLE_STEPS)


def test_each_tree_is_a_model_and_the_main_one_keeps_name_and_plugins() -> None:
    main, loose = joint_trees(pair())
    assert (main.name, main.canonical_link, [link.name for link in main.links]) == ("pair", "base", ["base", "arm"])
    assert [joint.name for joint in main.joints] == ["weld"] and len(main.plugins) == 1
    assert (loose.name, loose.canonical_link, [link.name for link in loose.links]) == (
        "pair::loose::block",
        "loose::block",
        ["loose::block"],
    )
    assert (loose.joints, loose.plugins, loose.pose) == ((), (), main.pose)


def test_one_tree_stays_whole_and_a_cycle_is_still_refused() -> None:
    main = joint_trees(pair())[0]
    assert joint_trees(main) == [main]
    cycle = replace(main, joints=(*main.joints, Joint("back", "fixed", "arm", "base")))
    assert joint_trees(cycle) == [cycle]
    with pytest.raises(DescriptionError, match="not one tree"):
        model_to_urdf(cycle)


def test_each_tree_falls_on_its_own_and_rests_on_the_ground(settled: Physics) -> None:
    """Body `pair` (base and arm) and body `pair::loose::block`, each box's centre 0.1 m up, where it fell."""
    assert set(settled.bodies) == {"ground", "pair", "pair::loose::block"}
    for body, link, xy in (
        ("pair", "base", (0, 0)),
        ("pair", "arm", (0.3, 0)),
        ("pair::loose::block", "loose::block", (2, 0)),
    ):
        (x, y, z), _ = settled.frame_pose(body, link)
        assert (x, y) == pytest.approx(xy, abs=1e-3), (body, link)
        assert z == pytest.approx(0.1, abs=CONTACT_SLOP), (body, link)
