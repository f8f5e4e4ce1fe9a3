"""ROS topic names to Zenoh keys: the zenoh-bridge-ros2dds mapping, and the names it refuses."""

from __future__ import annotations

import pytest

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
