"""ROS topic names to Zenoh keys: the zenoh-bridge-ros2dds mapping, and the names it refuses."""

from __future__ import annotations

import pytest

from simbot.bus import messages
from simbot.bus.frames import frame_prefix, prefixed_frame, with_frame_prefix
from simbot.bus.keys import topic_key


@pytest.mark.parametrize(
    ("topic", "namespace", "key"),
    [
        ("/cmd_vel", "", "cmd_vel"),
        ("cmd_vel", "", "cmd_vel"),
        ("/camera_front/camera_info", "", "camera_front/camera_info"),
        ("/model/trolley/pose", "", "model/trolley/pose"),
        ("/cmd_vel", "robot1", "robot1/cmd_vel"),
        ("/cmd_vel", "/robot1/", "robot1/cmd_vel"),
        ("tf_static/", "/fleet/robot1", "fleet/robot1/tf_static"),
        ("/detachable_joint/state", "/", "detachable_joint/state"),
    ],
)
def test_topic_key_maps_like_the_ros2_bridge(topic: str, namespace: str, key: str) -> None:
    """Leading and trailing slashes go; the namespace is a key prefix."""
    assert topic_key(topic, namespace) == key


@pytest.mark.parametrize(
    ("topic", "namespace", "reason"),
    [
        ("", "", "empty"),
        ("/", "ns", "empty"),
        ("/a//b", "", "empty chunk"),
        ("/cmd_vel", "a//b", "empty chunk"),
        ("/lidar_*", "", "special character"),
        ("/**", "", "special character"),
        ("/a/$*", "", "special character"),
        ("/a?x=1", "", "special character"),
        ("/a#b", "", "special character"),
        ("/cmd_vel", "robot*", "special character"),
        ("/@adv/x", "", "verbatim"),
        ("/a/ b", "", "whitespace"),
    ],
)
def test_topic_key_rejects_what_zenoh_would_misread(topic: str, namespace: str, reason: str) -> None:
    """Wildcards, selector characters, verbatim chunks and empty chunks: ValueError naming the topic."""
    with pytest.raises(ValueError, match=reason) as caught:
        topic_key(topic, namespace)
    assert repr(topic) in str(caught.value)
    assert "\n" not in str(caught.value)


def test_frame_prefix_puts_a_robots_frames_under_its_namespace() -> None:
    """Headers, child frames and each transform's frames go under the prefix; world, empty and prefixed ones stay."""
    tf = messages.tf_message(
        [
            messages.transform_stamped(0, "odom", "base_footprint", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
            messages.transform_stamped(0, "world", "tug_2/base_link", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
        ]
    )
    prefixed = with_frame_prefix(tf, "tug_2")
    pairs = [(t.header.frame_id, t.child_frame_id) for t in prefixed.transforms]
    assert pairs == [("tug_2/odom", "tug_2/base_footprint"), ("world", "tug_2/base_link")]
    assert tf.transforms[0].header.frame_id == "odom", "the message given is not changed"
    assert with_frame_prefix(messages.string("x"), "tug_2") == messages.string("x")
    assert (prefixed_frame("", "tug_2"), prefixed_frame("map", "tug_2"), frame_prefix("tug_2/base_link")) == (
        "",
        "map",
        "tug_2",
    )
