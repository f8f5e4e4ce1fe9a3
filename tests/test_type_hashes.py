"""simbot's ROS 2 type hashes (simbot/bus/type_hashes.py) against rosidl's own.

The ROS 2 message wheels ship, next to each .msg and .srv, the .json rosidl wrote with the type's
hash: every type of simbot's typestore that a wheel ships is checked against it. No wheel ships
tf2_msgs, vision_msgs or ros_gz_interfaces; those are checked against zenoh-ros2-sdk, an independent
implementation, given every definition from here (it never fetches one).
"""

from __future__ import annotations

import copy
import hashlib
import json
import sysconfig
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from simbot.bus.codec import ROS_GZ_INTERFACES, TYPESTORE, VISION_MSGS, UnknownMessageType
from simbot.bus.type_hashes import dds_type_name, ros_typename, type_hash

SERVICES = ["std_srvs/srv/Empty", "std_srvs/srv/SetBool", "std_srvs/srv/Trigger"]
HUMBLE_CHANGED = {
    "rmw_dds_common/msg/Gid",
    "rmw_dds_common/msg/NodeEntitiesInfo",
    "rmw_dds_common/msg/ParticipantEntitiesInfo",
    "sensor_msgs/msg/Range",
}
"""Types whose Humble definition (simbot's typestore) differs from the wheels' (Kilted): their hashes
differ by design; test_humble_changes checks that the difference is exactly the known one."""
TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms\n"
WHEEL_PACKAGES = {
    "builtin_interfaces",
    "std_msgs",
    "geometry_msgs",
    "sensor_msgs",
    "nav_msgs",
    "rosgraph_msgs",
    "visualization_msgs",
}


@pytest.fixture(scope="module")
def share() -> Path:
    """The wheels' share folder (the environment's data path), or a skip when they are not installed."""
    path = Path(sysconfig.get_path("data")) / "share"
    if not (path / "std_srvs" / "srv" / "Trigger.json").is_file():
        pytest.skip(f"no ROS 2 message wheels' .json under {path}: pip install -e '.[test]'")
    return path


def _wheel(share: Path, typename: str) -> dict[str, Any] | None:
    """The .json rosidl wrote for a type, or None when no installed wheel ships it."""
    path = share / f"{typename}.json"
    return json.loads(path.read_text()) if path.is_file() else None


def _hashes(wheel: dict[str, Any]) -> dict[str, str]:
    return {entry["type_name"]: entry["hash_string"] for entry in wheel["type_hashes"]}


def _rihs01(description: dict[str, Any]) -> str:
    """rosidl's hash of a TypeDescription: its JSON without default values (rosidl's calculate_type_hash)."""
    hashable = copy.deepcopy(description)
    for struct in [hashable["type_description"], *hashable["referenced_type_descriptions"]]:
        for field in struct["fields"]:
            del field["default_value"]
    text = json.dumps(hashable, separators=(", ", ": "))
    return f"RIHS01_{hashlib.sha256(text.encode()).hexdigest()}"


def _as_in_humble(description: dict[str, Any]) -> dict[str, Any]:
    """A Kilted wheel's TypeDescription with Humble's definitions of the types that changed since."""
    humble = copy.deepcopy(description)
    for struct in [humble["type_description"], *humble["referenced_type_descriptions"]]:
        if struct["type_name"] == "rmw_dds_common/msg/Gid":  # Humble's GID is char[24], later ones char[16]
            struct["fields"][0]["type"]["capacity"] = 24
        if struct["type_name"] == "sensor_msgs/msg/Range":  # `float32 variance` came after Humble
            struct["fields"] = [field for field in struct["fields"] if field["name"] != "variance"]
    return humble


def test_messages_match_the_wheels(share: Path) -> None:
    checked, mismatches = set(), []
    for typename in sorted(TYPESTORE.fielddefs.keys() - HUMBLE_CHANGED):
        wheel = _wheel(share, typename)
        if wheel is not None:
            checked.add(typename)
            expected = _hashes(wheel)[typename]
            if type_hash(typename) != expected:
                mismatches.append(f"{typename}: {type_hash(typename)} != the wheel's {expected}")
    assert not mismatches, "\n".join(mismatches)
    assert {typename.split("/")[0] for typename in checked} >= WHEEL_PACKAGES
    assert len(checked) > 100


@pytest.mark.parametrize("typename", sorted(HUMBLE_CHANGED))
def test_humble_changes(share: Path, typename: str) -> None:
    wheel = _wheel(share, typename)
    assert wheel is not None
    description, expected = wheel["type_description_msg"], _hashes(wheel)[typename]
    assert _rihs01(description) == expected  # the recipe here is rosidl's
    assert type_hash(typename) != expected
    assert type_hash(typename) == _rihs01(_as_in_humble(description))


@pytest.mark.parametrize("service", SERVICES)
def test_services_match_the_wheels(share: Path, service: str) -> None:
    """The service, its request, response and event, and the event's nested types."""
    wheel = _wheel(share, service)
    assert wheel is not None
    expected = _hashes(wheel)
    assert {f"{service}_Request", f"{service}_Response", f"{service}_Event"} < expected.keys()
    assert {typename: type_hash(typename) for typename in expected} == expected


@pytest.fixture(scope="module")
def sdk_hash() -> Callable[..., str]:
    return pytest.importorskip("zenoh_ros2_sdk.utils").get_type_hash


@pytest.fixture(scope="module")
def definitions(share: Path) -> dict[str, str]:
    """Every .msg text the checked types nest, by type name: the wheels' and codec's own."""
    wheels = {
        f"{package}/msg/{path.stem}": path.read_text()
        for package in ("builtin_interfaces", "std_msgs", "geometry_msgs")
        for path in sorted((share / package / "msg").glob("*.msg"))
    }
    return wheels | ROS_GZ_INTERFACES | VISION_MSGS | {"tf2_msgs/msg/TFMessage": TF_MESSAGE}


@pytest.mark.parametrize("typename", ["tf2_msgs/msg/TFMessage", *sorted(VISION_MSGS), *sorted(ROS_GZ_INTERFACES)])
def test_types_no_wheel_ships_match_the_sdk(
    sdk_hash: Callable[..., str], definitions: dict[str, str], typename: str
) -> None:
    expected = sdk_hash(typename, msg_definition=definitions[typename], dependencies=definitions)
    assert type_hash(typename) == expected


@pytest.mark.parametrize(
    "typename", ["geometry_msgs/msg/TransformStamped", "geometry_msgs/msg/PoseWithCovariance", "std_msgs/msg/UInt32"]
)
def test_the_sdk_agrees_with_the_wheels(
    share: Path, sdk_hash: Callable[..., str], definitions: dict[str, str], typename: str
) -> None:
    """The SDK, given definitions as above, is right where a wheel tells: a check of the check."""
    wheel = _wheel(share, typename)
    assert wheel is not None
    assert (
        sdk_hash(typename, msg_definition=definitions[typename], dependencies=definitions) == _hashes(wheel)[typename]
    )


def test_dds_type_names() -> None:
    assert dds_type_name("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    assert dds_type_name("std_srvs/srv/Empty") == "std_srvs::srv::dds_::Empty_"
    assert ros_typename("std_srvs::srv::dds_::Empty_") == "std_srvs/srv/Empty"
    for typename in [*TYPESTORE.fielddefs, *SERVICES]:
        assert ros_typename(dds_type_name(typename)) == typename


@pytest.mark.parametrize(
    "text", ["geometry_msgs/msg/Twist", "geometry_msgs::msg::Twist", "geometry_msgs::msg::dds_::Twist", "", "_"]
)
def test_ros_typename_of_other_text(text: str) -> None:
    assert ros_typename(text) is None


def test_dds_type_name_of_other_text() -> None:
    with pytest.raises(ValueError, match="not a ROS 2 type name"):
        dds_type_name("geometry_msgs::msg::dds_::Twist_")


@pytest.mark.parametrize(
    "typename", ["foo_msgs/msg/Bar", "std_srvs/srv/Nope", "std_srvs/srv/Nope_Event", "std_msgs/msg/String_Event"]
)
def test_unknown_types(typename: str) -> None:
    with pytest.raises(UnknownMessageType) as raised:
        type_hash(typename)
    assert typename in str(raised.value) and "\n" not in str(raised.value)
