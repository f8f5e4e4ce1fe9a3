"""StampSync groups messages of several streams by stamp; tf lookups chain transforms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simbot.bus import messages as m
from simbot.bus.sync import StampSync
from simbot.bus.tf_tree import TransformTree, planar_pose

MS = 1_000_000


def test_a_set_comes_out_when_its_last_member_arrives_within_slop() -> None:
    sync: StampSync[str] = StampSync(["a", "b", "c"], slop_ns=100 * MS, max_wait_ns=500 * MS)
    assert sync.add("a", 1000 * MS, "a1") == []
    assert sync.add("b", 1040 * MS, "b1") == []
    assert sync.add("c", 960 * MS, "c1") == [{"a": "a1", "b": "b1", "c": "c1"}]
    assert sync.add("a", 1200 * MS, "a2") == []
    assert sync.partial_sets == 0


def test_stamps_further_apart_than_slop_do_not_pair() -> None:
    sync: StampSync[str] = StampSync(["a", "b"], slop_ns=100 * MS, max_wait_ns=1000 * MS)
    assert sync.add("a", 0, "a0") == []
    assert sync.add("b", 150 * MS, "b0") == []
    assert sync.add("a", 200 * MS, "a1") == [{"a": "a1", "b": "b0"}]


def test_a_silent_stream_does_not_hold_the_other_back() -> None:
    """With b silent, each a comes out alone once a newer stamp is max_wait past it."""
    sync: StampSync[str] = StampSync(["a", "b"], slop_ns=10 * MS, max_wait_ns=300 * MS)
    out = []
    for i in range(6):
        out += sync.add("a", i * 200 * MS, f"a{i}")
    assert out == [{"a": f"a{i}", "b": None} for i in range(4)]
    assert sync.partial_sets == 4


def test_time_going_back_forgets_what_waits() -> None:
    sync: StampSync[str] = StampSync(["a", "b"], slop_ns=10 * MS, max_wait_ns=300 * MS)
    sync.add("a", 5000 * MS, "late")
    assert sync.add("a", 0, "a0") == []
    assert sync.resets == 1
    assert sync.add("b", 0, "b0") == [{"a": "a0", "b": "b0"}]


def test_a_restart_seen_first_on_an_emptied_stream_forgets_what_waits() -> None:
    """The first stamp of a new run is older than the newest its stream saw, even when the stream's
    queue was emptied by the last set: what waits on the other stream is forgotten, no partial set."""
    sync: StampSync[str] = StampSync(["a", "b"], slop_ns=10 * MS, max_wait_ns=300 * MS)
    sync.add("a", 8400 * MS, "a_old")
    assert sync.add("b", 8400 * MS, "b_old") == [{"a": "a_old", "b": "b_old"}]
    sync.add("a", 8600 * MS, "a_waiting")
    assert sync.add("b", 200 * MS, "b_new") == []
    assert sync.add("a", 200 * MS, "a_new") == [{"a": "a_new", "b": "b_new"}]
    assert (sync.resets, sync.partial_sets) == (1, 0)


def test_bad_configuration_is_refused() -> None:
    with pytest.raises(ValueError):
        StampSync(["a", "a"], 0, 0)
    with pytest.raises(ValueError):
        StampSync(["a"], 10, 5)
    with pytest.raises(KeyError):
        StampSync[None](["a"], 0, 0).add("b", 0, None)


def test_lookup_chains_transforms_between_branches() -> None:
    """base_link→lidar (yaw π, 1 m ahead) and base_link→cam (0.5 m up): a lidar point seen from cam."""
    tree = TransformTree()
    yaw_pi = (0.0, 0.0, 1.0, 0.0)
    tree.update(
        m.tf_message(
            [
                m.transform_stamped(0, "base_footprint", "base_link", (0, 0, 0.09), (0, 0, 0, 1)),
                m.transform_stamped(0, "base_link", "lidar", (1.0, 0, 0), yaw_pi),
                m.transform_stamped(0, "base_link", "cam", (0, 0, 0.5), (0, 0, 0, 1)),
            ]
        )
    )
    lidar_in_base = tree.lookup("base_footprint", "lidar")
    assert lidar_in_base is not None
    point = lidar_in_base @ np.array([2.0, 0.0, 0.0, 1.0])  # 2 m along the lidar's x = backwards
    assert point[:3] == pytest.approx([-1.0, 0.0, 0.09], abs=1e-12)
    lidar_in_cam = tree.lookup("cam", "lidar")
    assert lidar_in_cam is not None
    assert (lidar_in_cam @ np.array([0.0, 0.0, 0.0, 1.0]))[:3] == pytest.approx([1.0, 0.0, -0.5], abs=1e-12)
    assert tree.lookup("base_link", "nowhere") is None
    assert tree.frames == {"base_footprint", "base_link", "lidar", "cam"}


def test_planar_pose_reads_the_heading() -> None:
    half = math.radians(120) / 2
    msg = m.pose_stamped(0, "world", (1.0, -2.0, 0.1), (0.0, 0.0, math.sin(half), math.cos(half)))
    assert planar_pose(msg.pose) == pytest.approx((1.0, -2.0, math.radians(120)))


def test_a_zero_quaternion_in_tf_is_refused() -> None:
    tree = TransformTree()
    with pytest.raises(ValueError, match="zero norm"):
        tree.update(m.tf_message([m.transform_stamped(0, "base_link", "lidar", (0, 0, 0), (0, 0, 0, 0))]))
