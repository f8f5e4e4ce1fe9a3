"""The bus graph: every publisher, subscription and service announces its key, kind and type."""

from __future__ import annotations

from bus_helpers import node_pair, wait_until

from simbot.bus import messages as m
from simbot.bus.graph import Endpoint, discover, parse_token, token_key


def test_token_keys_round_trip_types_with_slashes() -> None:
    key = token_key("pub", "sensor_msgs/msg/LaserScan", "ns/lidar_front")
    assert key == "simbot_graph/pub/sensor_msgs%msg%LaserScan/ns/lidar_front"
    assert parse_token(key) == Endpoint("ns/lidar_front", "pub", "sensor_msgs/msg/LaserScan")
    assert parse_token("simbot_graph/bogus/x/y") is None
    assert parse_token("elsewhere/pub/t/k") is None


def test_a_client_discovers_what_the_server_and_another_client_declare_and_withdraw() -> None:
    """Untyped publishers appear at their first put; typed ones, subscriptions and services at once; closing withdraws them."""
    with node_pair() as pair:
        ns = pair.server.namespace
        publisher = pair.server.publisher("odom")
        publisher.put(m.twist())
        inbox = pair.server.inbox("cmd_vel", "geometry_msgs/msg/Twist")
        pair.server.queryable("world/w/state")
        pair.client.subscribe("odom", "geometry_msgs/msg/Twist", lambda _msg: None)
        silent = pair.server.publisher("never_put")
        pair.server.publisher("camera", m.Image)  # typed: on the graph before anything is put
        expected = {
            Endpoint(f"{ns}/camera", "pub", "sensor_msgs/msg/Image"),
            Endpoint(f"{ns}/odom", "pub", "geometry_msgs/msg/Twist"),
            Endpoint(f"{ns}/cmd_vel", "sub", "geometry_msgs/msg/Twist"),
            Endpoint(f"{ns}/world/w/state", "srv", "json"),
            Endpoint(f"{ns}/odom", "sub", "geometry_msgs/msg/Twist"),
        }
        wait_until(lambda: set(discover(pair.client.session, ns)) == expected, what="the five entities")
        assert all(e.key != silent.key for e in discover(pair.client.session, ns))
        inbox.close()
        wait_until(lambda: len(discover(pair.client.session, ns)) == 4, what="the inbox's withdrawal")
        assert discover(pair.client.session, "other_namespace") == []
