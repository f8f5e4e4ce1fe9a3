"""The bus graph: every publisher, subscription and service announces its topic, kind and type with
rmw_zenoh's liveliness tokens (JSON services with simbot's own), so ROS 2 tools list them too."""

from __future__ import annotations

from bus_helpers import node_pair, wait_until

from simbot.bus import messages as m
from simbot.bus.graph import Endpoint, discover, json_token, parse_token
from simbot.bus.type_hashes import type_hash


def test_tokens_are_rmw_zenohs_and_parse_back() -> None:
    """An rmw_zenoh publisher token (namespace and topic mangled with %) names its topic and type."""
    token = (
        "@ros2_lv/0/2a6b62ff9479a5a56fe0b6fdf114f968/0/3/MP/%/%ns/simbot/%ns%lidar_front/"
        f"sensor_msgs::msg::dds_::LaserScan_/{type_hash('sensor_msgs/msg/LaserScan')}/2::,10:,:,:,,"
    )
    assert parse_token(token) == Endpoint("ns/lidar_front", "pub", "sensor_msgs/msg/LaserScan")
    assert parse_token(json_token("ns/world/w/state")) == Endpoint("ns/world/w/state", "srv", "json")
    node = "@ros2_lv/0/2a6b62ff9479a5a56fe0b6fdf114f968/0/0/NN/%/%ns/simbot"
    assert parse_token(node) is None, "a node is no endpoint"
    assert parse_token("@ros2_lv/0/z/0/3/MP/%/%/n/%t/not_a_dds_type/h/q") is None
    assert parse_token("elsewhere/pub/t/k") is None


def test_a_client_discovers_what_the_server_and_another_client_declare_and_withdraw() -> None:
    """Publishers, subscriptions and services are on the graph from their declaration; closing withdraws them."""
    with node_pair() as pair:
        ns = pair.server.namespace
        pair.server.publisher("odom", m.Twist).put(m.twist())
        inbox = pair.server.inbox("cmd_vel", "geometry_msgs/msg/Twist")
        pair.server.queryable("world/w/state")
        pair.server.ros_service("world/w/reset", "std_srvs/srv/Empty")
        pair.client.subscribe("odom", "geometry_msgs/msg/Twist", lambda _msg: None)
        pair.server.publisher("camera", m.Image)
        expected = {
            Endpoint(f"{ns}/camera", "pub", "sensor_msgs/msg/Image"),
            Endpoint(f"{ns}/odom", "pub", "geometry_msgs/msg/Twist"),
            Endpoint(f"{ns}/cmd_vel", "sub", "geometry_msgs/msg/Twist"),
            Endpoint(f"{ns}/world/w/state", "srv", "json"),
            Endpoint(f"{ns}/world/w/reset", "srv", "std_srvs/srv/Empty"),
            Endpoint(f"{ns}/odom", "sub", "geometry_msgs/msg/Twist"),
        }
        wait_until(lambda: set(discover(pair.client.session, ns)) == expected, what="the six entities")
        inbox.close()
        wait_until(lambda: len(discover(pair.client.session, ns)) == 5, what="the inbox's withdrawal")
        assert discover(pair.client.session, "other_namespace") == []
