"""The CDR codec against golden bytes, round trips of every message constructor, and strict decoding."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from simbot.bus import messages
from simbot.bus.codec import DecodeError, EncodeError, UnknownMessageType, decode, encode, message_type

TWIST_GOLDEN = bytes.fromhex(
    "00 01 00 00"  # encapsulation: CDR little-endian, options 0
    "00 00 00 00 00 00 e0 3f"  # linear.x = 0.5
    "00 00 00 00 00 00 f0 bf"  # linear.y = -1.0
    "00 00 00 00 00 00 00 00"  # linear.z = 0.0
    "00 00 00 00 00 00 00 00"  # angular.x = 0.0
    "00 00 00 00 00 00 00 00"  # angular.y = 0.0
    "00 00 00 00 00 00 d0 3f"  # angular.z = 0.25
)
STRING_GOLDEN = bytes.fromhex(
    "00 01 00 00"  # encapsulation: CDR little-endian
    "03 00 00 00"  # data: length 3, the NUL included
    "68 69 00"  # 'h' 'i' NUL
)
CLOCK_GOLDEN = bytes.fromhex(
    "00 01 00 00"  # encapsulation: CDR little-endian
    "01 00 00 00"  # clock.sec = 1 (int32)
    "00 65 cd 1d"  # clock.nanosec = 500000000 (uint32)
)
EMPTY_GOLDEN = bytes.fromhex(
    "00 01 00 00"  # encapsulation: CDR little-endian
    "00"  # structure_needs_at_least_one_member = 0
)


def assert_same_message(actual: Any, expected: Any, path: str = "msg") -> None:
    """Field by field: floats within 1e-12, numpy arrays element-wise, the rest equal."""
    if dataclasses.is_dataclass(expected):
        assert type(actual) is type(expected), path
        for field in dataclasses.fields(expected):
            assert_same_message(getattr(actual, field.name), getattr(expected, field.name), f"{path}.{field.name}")
    elif isinstance(expected, np.ndarray):
        assert isinstance(actual, np.ndarray), path
        assert actual.dtype == expected.dtype, path
        np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-12, err_msg=path)
    elif isinstance(expected, list):
        assert len(actual) == len(expected), path
        for i, (a, e) in enumerate(zip(actual, expected)):
            assert_same_message(a, e, f"{path}[{i}]")
    elif isinstance(expected, float):
        assert actual == pytest.approx(expected, abs=1e-12), path
    else:
        assert actual == expected, path


def test_twist_golden_bytes() -> None:
    """A Twist is the header and six little-endian float64, with no padding."""
    msg = messages.twist((0.5, -1.0, 0.0), (0.0, 0.0, 0.25))
    assert encode(msg) == TWIST_GOLDEN
    decoded = decode(TWIST_GOLDEN, "geometry_msgs/msg/Twist")
    assert (decoded.linear.x, decoded.linear.y, decoded.angular.z) == (0.5, -1.0, 0.25)


def test_string_golden_bytes() -> None:
    """A String is a uint32 length that counts the terminating NUL, then the bytes and the NUL."""
    assert encode(messages.string("hi")) == STRING_GOLDEN
    assert decode(STRING_GOLDEN, "std_msgs/msg/String").data == "hi"


def test_clock_and_empty_golden_bytes() -> None:
    """Clock is int32 sec + uint32 nanosec from integer nanoseconds; Empty is one byte."""
    assert encode(messages.clock(1_500_000_000)) == CLOCK_GOLDEN
    assert messages.stamp_ns(decode(CLOCK_GOLDEN, "rosgraph_msgs/msg/Clock").clock) == 1_500_000_000
    assert encode(messages.empty()) == EMPTY_GOLDEN


ALTIMETER_GOLDEN = bytes.fromhex(
    "00 01 00 00"  # encapsulation: CDR little-endian
    "02 00 00 00 03 00 00 00"  # header.stamp: sec 2, nanosec 3
    "02 00 00 00 61 00 00 00"  # header.frame_id: length 2, 'a' NUL, padding to 8
    "00 00 00 00 00 00 f4 3f"  # vertical_position = 1.25 (float64)
    "00 00 00 00 00 00 e0 bf"  # vertical_velocity = -0.5
    "00 00 00 00 00 00 34 40"  # vertical_reference = 20.0
)


def test_gazebos_altimeter_golden_bytes() -> None:
    """ros_gz_interfaces/Altimeter, registered beside ROS 2 Humble's types: the header, then three float64."""
    assert encode(messages.altimeter(2_000_000_003, "a", 1.25, -0.5, 20.0)) == ALTIMETER_GOLDEN
    assert decode(ALTIMETER_GOLDEN, "ros_gz_interfaces/msg/Altimeter").vertical_reference == 20.0


def test_a_lidar_point_is_packed_as_gazebo_packs_it() -> None:
    """x y z intensity float32 then ring uint16: 18 bytes a point, no padding; row r has ring r."""
    msg = messages.lidar_points(0, "velo", np.array([[[1.0, -2.0, 0.5]], [[0.0, 0.0, 0.0]]], dtype=np.float32))
    assert (msg.point_step, msg.row_step, msg.height, msg.width) == (18, 18, 2, 1)
    assert bytes(msg.data[18:]) == bytes.fromhex(
        "00 00 00 00"  # x = 0.0
        "00 00 00 00"  # y = 0.0
        "00 00 00 00"  # z = 0.0
        "00 00 00 00"  # intensity = 0.0
        "01 00"  # ring = 1 (uint16)
    )
    assert bytes(msg.data[:4]) == bytes.fromhex("00 00 80 3f")  # x = 1.0


def _every_constructor() -> dict[str, Any]:
    ns = 12_345_678_901
    quat = (0.0, 0.0, math.sin(0.3), math.cos(0.3))
    transform = messages.transform_stamped(ns, "base_link", "imu_link", (0.1, -0.2, 0.06), quat)
    covariance = np.arange(36, dtype=np.float64) * 1e-3
    return {
        "time_msg": messages.time_msg(ns),
        "header": messages.header(ns, "odom"),
        "vector3": messages.vector3(1.5, -2.25, 3.0),
        "quaternion": messages.quaternion(*quat),
        "transform_stamped": transform,
        "tf_message": messages.tf_message(
            [transform, messages.transform_stamped(ns, "odom", "base_footprint", (1, 2, 0), quat)]
        ),
        "string": messages.string("<robot name='flexley_tug'/> ünïcode"),
        "empty": messages.empty(),
        "clock": messages.clock(ns),
        "twist": messages.twist((0.5, 0.0, 0.0), (0.0, 0.0, -0.5)),
        "pose_stamped": messages.pose_stamped(ns, "world", (1.0, 0.2, 0.0), quat),
        "odometry": messages.odometry(
            ns,
            "odom",
            "base_footprint",
            (1.0, 2.0, 0.0),
            quat,
            (0.4, 0.0, 0.0),
            (0.0, 0.0, 0.1),
            covariance,
            covariance[::-1],
        ),
        "joint_state": messages.joint_state(
            ns, ["front_left_wheel_joint", "front_right_wheel_joint"], [0.5, -1.5], [2.0, 2.5], []
        ),
        "magnetic_field": messages.magnetic_field(ns, "mag", (5.5e-6, 2.3e-5, -4.2e-5), (1e-14, 1e-14, 4e-14)),
        "fluid_pressure": messages.fluid_pressure(ns, "baro", 101325.0, 0.25),
        "nav_sat_fix": messages.nav_sat_fix(ns, "gps", (47.3, 8.5, 400.0), (4.0, 4.0, 9.0)),
        "wrench_stamped": messages.wrench_stamped(ns, "ft", (0.0, 0.0, -19.6), (0.0, 5.88, 0.0)),
        "altimeter": messages.altimeter(ns, "alt", 1.25, -0.5, 20.0),
        "contacts": messages.contacts(
            ns,
            "bump",
            [
                messages.ContactPair(
                    "a::b::c", "g::l::c", [(0.1, 0.2, 0.0)] * 2, [(0, 0, 1)] * 2, [1e-4, 2e-4], [(0, 0, 9.8)] * 2
                )
            ],
        ),
        "lidar_points": messages.lidar_points(ns, "velo", np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)),
    }


@pytest.mark.parametrize("name", sorted(_every_constructor()))
def test_round_trip_of_every_constructor(name: str) -> None:
    """encode → decode gives the same message back, and decoding consumes every byte."""
    msg = _every_constructor()[name]
    data = encode(msg)
    assert data[:4] == b"\x00\x01\x00\x00"
    assert_same_message(decode(data, msg.__msgtype__), msg)
    assert encode(decode(data, msg.__msgtype__)) == data


def test_constructor_values_land_in_the_right_fields() -> None:
    """Spot checks of the nesting: stamps, frames, covariance layout, joint arrays."""
    msgs = _every_constructor()
    assert messages.stamp_ns(msgs["header"]) == 12_345_678_901
    assert (msgs["time_msg"].sec, msgs["time_msg"].nanosec) == (12, 345_678_901)
    odom = decode(encode(msgs["odometry"]), "nav_msgs/msg/Odometry")
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    assert odom.pose.pose.position.y == 2.0 and odom.twist.twist.angular.z == 0.1
    assert odom.pose.covariance[35] == pytest.approx(0.035) and odom.twist.covariance[0] == pytest.approx(0.035)
    joints = decode(encode(msgs["joint_state"]), "sensor_msgs/msg/JointState")
    assert joints.name == ["front_left_wheel_joint", "front_right_wheel_joint"]
    np.testing.assert_array_equal(joints.position, [0.5, -1.5])
    assert joints.effort.size == 0
    tf = decode(encode(msgs["tf_message"]), "tf2_msgs/msg/TFMessage")
    assert [t.child_frame_id for t in tf.transforms] == ["imu_link", "base_footprint"]
    assert tf.transforms[0].transform.translation.z == pytest.approx(0.06)


def test_time_msg_of_negative_and_exact_seconds() -> None:
    """nanosec stays in [0, 1e9): -1 ns is sec -1 + 999999999 ns, as ROS writes it."""
    assert (messages.time_msg(-1).sec, messages.time_msg(-1).nanosec) == (-1, 999_999_999)
    assert (messages.time_msg(3_000_000_000).sec, messages.time_msg(3_000_000_000).nanosec) == (3, 0)
    assert messages.stamp_ns(messages.time_msg(-1)) == -1


def test_constructors_refuse_wrong_sizes() -> None:
    """A 35-value covariance or mismatched joint arrays are ValueErrors, not bad CDR."""
    with pytest.raises(ValueError, match="pose covariance: expected 36"):
        messages.odometry(0, "odom", "base", (0, 0, 0), (0, 0, 0, 1), (0, 0, 0), (0, 0, 0), [0.0] * 35)
    with pytest.raises(ValueError, match="positions for 2 joints"):
        messages.joint_state(0, ["a", "b"], [1.0])
    with pytest.raises(ValueError, match="velocities for 2 joints"):
        messages.joint_state(0, ["a", "b"], [1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="quaternion"):
        messages.pose_stamped(0, "world", (0, 0, 0), (0, 0, 1))


def test_trailing_alignment_padding_is_accepted() -> None:
    """Middlewares pad to alignment: up to 7 trailing bytes decode; 8 do not."""
    assert decode(STRING_GOLDEN + b"\x00" * 7, "std_msgs/msg/String").data == "hi"
    assert decode(bytearray(TWIST_GOLDEN + b"\x00" * 4), "geometry_msgs/msg/Twist").linear.x == 0.5
    assert decode(memoryview(TWIST_GOLDEN), "geometry_msgs/msg/Twist").angular.z == 0.25
    with pytest.raises(DecodeError, match="8 trailing bytes"):
        decode(TWIST_GOLDEN + b"\x00" * 8, "geometry_msgs/msg/Twist")


def _random(size: int, seed: int) -> bytes:
    return np.random.default_rng(seed).bytes(size)


@pytest.mark.parametrize(
    ("data", "typename", "reason"),
    [
        (b"", "geometry_msgs/msg/Twist", "shorter than the 4-byte"),
        (b"\x00\x01\x00", "std_msgs/msg/Empty", "shorter than the 4-byte"),
        (TWIST_GOLDEN[:-1], "geometry_msgs/msg/Twist", "Twist"),
        (TWIST_GOLDEN[:4], "geometry_msgs/msg/Twist", "Twist"),
        (STRING_GOLDEN[:-2], "std_msgs/msg/String", "String"),
        (b"\x00\x00\x00\x00" + TWIST_GOLDEN[4:], "geometry_msgs/msg/Twist", "not CDR little-endian"),
        (b"\x00\x03\x00\x00" + TWIST_GOLDEN[4:], "geometry_msgs/msg/Twist", "not CDR little-endian"),
        (b"\x01\x00\x00\x00" + TWIST_GOLDEN[4:], "geometry_msgs/msg/Twist", "not CDR little-endian"),
        (_random(52, seed=1), "geometry_msgs/msg/Twist", "not CDR little-endian"),
        (b"\x00\x01\x00\x00" + _random(100, seed=2), "geometry_msgs/msg/Twist", "trailing bytes"),
        (b"\x00\x01\x00\x00" + _random(100, seed=3), "std_msgs/msg/String", "String"),
        (b"\x00\x01\x00\x00" + _random(100, seed=4), "nav_msgs/msg/Odometry", "Odometry"),
        (STRING_GOLDEN, "geometry_msgs/msg/Twist", "Twist"),
        (TWIST_GOLDEN, "std_msgs/msg/String", "String"),
        (CLOCK_GOLDEN, "geometry_msgs/msg/Twist", "Twist"),
        (TWIST_GOLDEN, "rosgraph_msgs/msg/Clock", "trailing bytes"),
        (bytes.fromhex("00 01 00 00 03 00 00 00 ff fe 00"), "std_msgs/msg/String", "String"),
    ],
    ids=[
        "empty",
        "three-bytes",
        "twist-less-one",
        "twist-header-only",
        "string-truncated",
        "big-endian",
        "unknown-encapsulation",
        "swapped-header",
        "random",
        "random-body-as-twist",
        "random-body-as-string",
        "random-body-as-odometry",
        "string-as-twist",
        "twist-as-string",
        "clock-as-twist",
        "twist-as-clock",
        "invalid-utf8",
    ],
)
def test_decode_is_strict(data: bytes, typename: str, reason: str) -> None:
    """Truncated, foreign, random or mistyped payloads are one-line DecodeErrors, nothing else."""
    with pytest.raises(DecodeError, match=reason) as caught:
        decode(data, typename)
    assert "\n" not in str(caught.value)
    assert isinstance(caught.value, ValueError)


def test_unknown_type_names_and_non_messages() -> None:
    """A misspelt type fails loudly (not as a DecodeError); encoding a non-message is an EncodeError."""
    with pytest.raises(UnknownMessageType, match="geometry_msgs/msg/Twits"):
        message_type("geometry_msgs/msg/Twits")
    with pytest.raises(UnknownMessageType):
        decode(TWIST_GOLDEN, "geometry_msgs/msg/Twits")
    assert message_type("geometry_msgs/msg/Twist") is messages.Twist
    with pytest.raises(EncodeError, match="not a rosbags message"):
        encode({"linear": 0.5})
    with pytest.raises(EncodeError, match="std_msgs/msg/String"):
        encode(messages.String(data=42))  # type: ignore[arg-type]


def test_image_pixels_undoes_image_and_drops_row_padding() -> None:
    """`image_pixels` is the inverse of `image`, for rgb8 and mono8, and skips the padding a step may hold."""
    rng = np.random.default_rng(7)
    colour = rng.integers(0, 256, size=(5, 4, 3), dtype=np.uint8)
    grey = rng.integers(0, 256, size=(5, 4), dtype=np.uint8)
    for pixels in (colour, grey):
        back = messages.image_pixels(decode(encode(messages.image(0, "cam", pixels)), "sensor_msgs/msg/Image"))
        assert np.array_equal(back, pixels)
    padded = messages.image(0, "cam", np.zeros((5, 6, 3), dtype=np.uint8))  # rows of 18 bytes
    padded.data[:] = np.hstack([colour.reshape(5, 12), np.full((5, 6), 255, dtype=np.uint8)]).reshape(-1)
    padded.width = 4
    assert np.array_equal(messages.image_pixels(padded), colour)
    short = messages.image(0, "cam", colour)
    short.data = short.data[:-1]
    with pytest.raises(ValueError, match="59 bytes with step 12 cannot hold 5 rows of 4 rgb8 pixels"):
        messages.image_pixels(short)
    short.encoding = "32FC1"
    with pytest.raises(ValueError, match="encoding '32FC1' is not one of"):
        messages.image_pixels(short)
