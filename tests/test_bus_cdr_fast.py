"""The fixed-layout CDR writers (simbot/bus/fixed_cdr.py) against rosbags' generic serializer: the same
bytes for every message, and the same error for every bad one; and a real server whose five hot
types never fall back from them (the registry's count, simbot/bus/encoders.py).

Random messages of each of the five types, with frame ids of every byte length from 0 to 17 (every
padding case after a string), non-ASCII UTF-8, stamps over the whole int32/uint32 range, NaN, ±inf,
-0.0 and subnormal values, covariances with random entries, and scans of 0, 1, odd and even rays.
"""

from __future__ import annotations

import dataclasses
import math
import random
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bus_helpers import endpoint, free_port, unique_namespace, wait_until
from conftest import REPO, ROBOT_SDF

from simbot.bus import BusOptions, Node, messages
from simbot.bus.codec import ENCODERS, TYPESTORE, EncodeError, decode, encode, serialize
from simbot.bus.encoders import Encoders
from simbot.bus.fixed_cdr import WRITERS
from simbot.bus.frames import with_frame_prefix
from simbot.bus.type_hashes import dds_type_name
from simbot.sim.loop.simulation import Mode
from simbot.sim.server import Server, ServerConfig

MESSAGES_PER_TYPE = 300
ALPHABET = "abcxyz_/0189" + "éß°→€🤖"  # 1-byte ASCII, 2-, 3- and 4-byte UTF-8
SPECIAL = (math.nan, math.inf, -math.inf, -0.0, 0.0, 5e-324, 1.7976931348623157e308, -1e-300)
SPECIAL_32 = tuple(
    float(np.float32(v)) for v in (math.nan, math.inf, -math.inf, -0.0, 0.0, 1e-45, 3.4028235e38, -1e-38)
)
SCAN_SIZES = (0, 1, 2, 3, 360, 719, 720, 1081)
ASCII_FIRST = 144


def text(rng: random.Random, index: int) -> str:
    """A frame id: ASCII of byte length index % 18 for the first messages (every padding case), then
    random characters of 1 to 4 UTF-8 bytes, empty now and then."""
    if index < ASCII_FIRST:
        return "f" * (index % 18)
    return "".join(rng.choice(ALPHABET) for _ in range(rng.choice((0, 1, 2, 5, 9, 14, 23))))


def number(rng: random.Random) -> float:
    """A float64: mostly random magnitudes and signs, sometimes NaN, ±inf, -0.0 or a subnormal."""
    if rng.random() < 0.15:
        return rng.choice(SPECIAL)
    return rng.uniform(-1, 1) * 10 ** rng.randint(-12, 12)


def number_32(rng: random.Random) -> float:
    """A float32 field's value, as the wire can carry it (so that a round trip gives it back)."""
    if rng.random() < 0.15:
        return rng.choice(SPECIAL_32)
    return float(np.float32(rng.uniform(-1, 1) * 10 ** rng.randint(-6, 6)))


def floats(rng: random.Random, size: int, dtype: type[np.floating[Any]] = np.float64) -> np.ndarray[Any, Any]:
    """An array of `size` values, NaN and ±inf among them."""
    pick = number_32 if dtype is np.float32 else number
    return np.array([pick(rng) for _ in range(size)], dtype=dtype)


def header(rng: random.Random, index: int) -> Any:
    stamp = messages.Time(sec=rng.randint(-(2**31), 2**31 - 1), nanosec=rng.randint(0, 2**32 - 1))
    return messages.Header(stamp=stamp, frame_id=text(rng, index))


def vector(rng: random.Random) -> Any:
    return messages.Vector3(x=number(rng), y=number(rng), z=number(rng))


def quaternion(rng: random.Random) -> Any:
    return messages.Quaternion(x=number(rng), y=number(rng), z=number(rng), w=number(rng))


def imu(rng: random.Random, index: int) -> Any:
    return messages.Imu(
        header=header(rng, index),
        orientation=quaternion(rng),
        orientation_covariance=floats(rng, 9),
        angular_velocity=vector(rng),
        angular_velocity_covariance=floats(rng, 9),
        linear_acceleration=vector(rng),
        linear_acceleration_covariance=floats(rng, 9),
    )


def odometry(rng: random.Random, index: int) -> Any:
    pose = messages.Pose(
        position=messages.Point(x=number(rng), y=number(rng), z=number(rng)), orientation=quaternion(rng)
    )
    return messages.Odometry(
        header=header(rng, index),
        child_frame_id=text(rng, index // 18 if index < ASCII_FIRST else index),  # every pair of lengths mod 8
        pose=messages.PoseWithCovariance(pose=pose, covariance=floats(rng, 36)),
        twist=messages.TwistWithCovariance(
            twist=messages.Twist(linear=vector(rng), angular=vector(rng)), covariance=floats(rng, 36)
        ),
    )


def transform(rng: random.Random, index: int) -> Any:
    return messages.TransformStamped(
        header=header(rng, index),
        child_frame_id=text(rng, rng.randrange(200)),
        transform=messages.Transform(translation=vector(rng), rotation=quaternion(rng)),
    )


def tf_message(rng: random.Random, index: int) -> Any:
    count = (0, 1, 2, 3, 7)[index % 5]
    return messages.TFMessage(transforms=[transform(rng, index + k) for k in range(count)])


def clock(rng: random.Random, index: int) -> Any:
    return messages.Clock(clock=header(rng, index).stamp)


def laser_scan(rng: random.Random, index: int) -> Any:
    size = SCAN_SIZES[index % len(SCAN_SIZES)]
    return messages.LaserScan(
        header=header(rng, index),
        angle_min=number_32(rng),
        angle_max=number_32(rng),
        angle_increment=number_32(rng),
        time_increment=number_32(rng),
        scan_time=number_32(rng),
        range_min=number_32(rng),
        range_max=number_32(rng),
        ranges=floats(rng, size, np.float32),
        intensities=floats(rng, rng.choice((0, size, 1, 5)), np.float32),
    )


BUILDERS: dict[str, Callable[[random.Random, int], Any]] = {
    "sensor_msgs/msg/Imu": imu,
    "nav_msgs/msg/Odometry": odometry,
    "tf2_msgs/msg/TFMessage": tf_message,
    "rosgraph_msgs/msg/Clock": clock,
    "sensor_msgs/msg/LaserScan": laser_scan,
}


def rosbags_bytes(msg: Any) -> bytes:
    """What rosbags writes: the reference, encapsulation header included."""
    return bytes(TYPESTORE.serialize_cdr(msg, msg.__msgtype__, little_endian=True))


def rosbags_error(msg: Any) -> str:
    """The EncodeError rosbags' path gives `msg` (the codec's wording around rosbags' exception)."""
    try:
        TYPESTORE.serialize_cdr(msg, msg.__msgtype__, little_endian=True)
    except Exception as exc:
        return f"cannot encode {msg.__msgtype__}: {' '.join(str(exc).split())}"
    raise AssertionError(f"rosbags encodes {msg!r}")


def frame_ids(msg: Any) -> list[str]:
    """Every frame id a message holds, in order (decoded strings, compared as text)."""
    stamped = [msg, *getattr(msg, "transforms", ())]
    headers = [m.header.frame_id for m in stamped if hasattr(m, "header")]
    return headers + [m.child_frame_id for m in stamped if hasattr(m, "child_frame_id")]


def random_messages(typename: str) -> Iterator[Any]:
    rng = random.Random(typename)
    for index in range(MESSAGES_PER_TYPE):
        yield BUILDERS[typename](rng, index)


def test_every_fixed_layout_type_has_a_writer_under_test() -> None:
    assert set(BUILDERS) == set(WRITERS)


@pytest.mark.parametrize("typename", sorted(BUILDERS))
def test_random_messages_are_written_byte_for_byte_as_rosbags_writes_them(typename: str) -> None:
    """The writer itself answers (no fallback), with rosbags' bytes; encode gives the same; and decode gives
    back the message, every bit of every field (NaN and -0.0 included): rosbags writes it to the same bytes."""
    for msg in random_messages(typename):
        expected = rosbags_bytes(msg)
        assert ENCODERS.fast(msg, typename) == expected, msg
        assert encode(msg) == expected
        decoded = decode(expected, typename)
        assert type(decoded) is type(msg) and rosbags_bytes(decoded) == expected
        assert frame_ids(decoded) == frame_ids(msg)


def test_every_padding_case_after_the_frame_ids_is_covered() -> None:
    """The random messages hold frame ids of every length mod 8, and Odometry every pair of them."""
    imu_lengths = {len(m.header.frame_id.encode()) % 8 for m in random_messages("sensor_msgs/msg/Imu")}
    odometry_pairs = {
        (len(m.header.frame_id.encode()) % 8, len(m.child_frame_id.encode()) % 8)
        for m in random_messages("nav_msgs/msg/Odometry")
    }
    assert imu_lengths == set(range(8))
    assert len(odometry_pairs) == 64


def test_the_servers_messages_with_a_robots_frame_prefix() -> None:
    """As the systems publish them: built by the constructors, then under a model's namespace (non-ASCII too)."""
    ns, quat = 12_345_678_901, (0.0, 0.0, math.sin(0.3), math.cos(0.3))
    built = [
        messages.imu(ns, "imu_link", quat, (0.1, -0.2, 0.3), (0.0, 0.0, 9.81), ((1e-4,) * 9, (2e-4,) * 9, (3e-4,) * 9)),
        messages.odometry(ns, "odom", "base_footprint", (1, 2, 0), quat, (0.5, 0, 0), (0, 0, 0.2), [1e-3] * 36),
        messages.tf_message(
            [
                messages.transform_stamped(ns, "odom", "base_footprint", (1, 2, 0), quat),
                messages.transform_stamped(ns, "base_link", "base_scan_front", (0.99, 0, 0.17), quat),
            ]
        ),
        messages.clock(ns),
        messages.laser_scan(
            ns, "base_scan_front", (-1.396263, 1.396263, 0.00388), (0.0, 0.1), (0.08, 10.0), [1.5, np.inf] * 360
        ),
    ]
    for prefix in ("", "tug_2", "tug_17", "chariot_é"):
        for msg in built:
            prefixed = with_frame_prefix(msg, prefix)
            data = ENCODERS.fast(prefixed, prefixed.__msgtype__)
            assert data is not None and data == rosbags_bytes(prefixed)
            if prefix and hasattr(prefixed, "header"):
                assert decode(data, prefixed.__msgtype__).header.frame_id.startswith(prefix + "/")


def bad_messages() -> dict[str, Any]:
    """Messages with one bad field each, and the field."""
    rng = random.Random(48)
    scan, odom, tf, clk, imu_msg = (
        laser_scan(rng, 5),
        odometry(rng, 3),
        tf_message(rng, 2),
        clock(rng, 0),
        imu(rng, 1),
    )
    first = tf.transforms[0]
    return {
        "imu covariance of 8": dataclasses.replace(imu_msg, orientation_covariance=np.zeros(8)),
        "imu covariance of 3×3": dataclasses.replace(imu_msg, angular_velocity_covariance=np.zeros((3, 3))),
        "imu covariance strided": dataclasses.replace(imu_msg, linear_acceleration_covariance=np.zeros(18)[::2]),
        "imu covariance float32": dataclasses.replace(imu_msg, orientation_covariance=np.zeros(9, np.float32)),
        "imu rate a string": dataclasses.replace(imu_msg, angular_velocity=messages.Vector3(x="fast", y=0.0, z=0.0)),  # type: ignore[arg-type]  # the bad field
        "imu frame a lone surrogate": dataclasses.replace(
            imu_msg, header=messages.Header(first.header.stamp, "\udc80")
        ),
        "odometry covariance a list": dataclasses.replace(
            odom,
            pose=messages.PoseWithCovariance(pose=odom.pose.pose, covariance=[0.0] * 36),  # type: ignore[arg-type]  # the bad field
        ),
        "odometry covariance of 35": dataclasses.replace(
            odom, twist=messages.TwistWithCovariance(twist=odom.twist.twist, covariance=np.zeros(35))
        ),
        "odometry child frame None": dataclasses.replace(odom, child_frame_id=None),
        "tf child frame bytes": messages.TFMessage(transforms=[dataclasses.replace(first, child_frame_id=b"x")]),
        "tf translation None": messages.TFMessage(
            transforms=[dataclasses.replace(first, transform=messages.Transform(translation=None, rotation=None))]  # type: ignore[arg-type]  # the bad field
        ),
        "clock sec past int32": messages.Clock(clock=messages.Time(sec=2**31, nanosec=0)),
        "clock nanosec negative": dataclasses.replace(clk, clock=messages.Time(sec=0, nanosec=-1)),
        "clock sec a float": messages.Clock(clock=messages.Time(sec=1.5, nanosec=0)),  # type: ignore[arg-type]  # the bad field
        "scan ranges float64": dataclasses.replace(scan, ranges=np.ones(5)),
        "scan ranges a list": dataclasses.replace(scan, ranges=[1.0, 2.0]),
        "scan intensities 2-D": dataclasses.replace(scan, intensities=np.ones((2, 2), np.float32)),
        "scan angle past float32": dataclasses.replace(scan, angle_min=1e39),
        "scan range_max None": dataclasses.replace(scan, range_max=None),
    }


@pytest.mark.parametrize("name", sorted(bad_messages()))
def test_a_bad_field_gives_the_error_rosbags_gives(name: str) -> None:
    """The writer declines (None, counted once against the type), and encode raises the one-line
    EncodeError of rosbags' path, word for word."""
    msg = bad_messages()[name]
    registry = Encoders(WRITERS, serialize)
    assert registry.fast(msg, msg.__msgtype__) is None
    assert registry.fallbacks() == {msg.__msgtype__: 1}
    with pytest.raises(EncodeError) as caught:
        encode(msg)
    assert str(caught.value) == rosbags_error(msg)
    assert "\n" not in str(caught.value)


def unusual_but_valid() -> dict[str, Any]:
    """Fields rosbags writes although the constructors never build them so: whichever path writes them,
    the bytes must be rosbags'."""
    rng = random.Random(7)
    imu_msg, scan, odom = imu(rng, 9), laser_scan(rng, 6), odometry(rng, 4)
    return {
        "covariance big-endian": dataclasses.replace(imu_msg, orientation_covariance=floats(rng, 9).astype(">f8")),
        "covariance int64": dataclasses.replace(imu_msg, orientation_covariance=np.arange(9)),
        "numpy scalars": dataclasses.replace(
            imu_msg, linear_acceleration=messages.Vector3(x=np.float32(0.1), y=np.float64(2), z=True)
        ),
        "ints for floats": dataclasses.replace(scan, angle_min=1, range_max=np.int16(30)),
        "numpy ints for a stamp": messages.Clock(clock=messages.Time(sec=np.int64(-5), nanosec=np.uint32(7))),
        "transforms a tuple": messages.TFMessage(transforms=tuple(tf_message(rng, 4).transforms)),  # type: ignore[arg-type]  # the unusual field
        "frame with a NUL": dataclasses.replace(odom, child_frame_id="a\0b"),
        "ranges read-only view": dataclasses.replace(scan, ranges=np.frombuffer(scan.ranges.tobytes(), np.float32)),
    }


@pytest.mark.parametrize("name", sorted(unusual_but_valid()))
def test_unusual_fields_still_give_rosbags_bytes(name: str) -> None:
    msg = unusual_but_valid()[name]
    assert encode(msg) == rosbags_bytes(msg)


def test_the_servers_hot_types_never_fall_back(tmp_path: Path) -> None:
    """A real server's tug, stepped in lockstep with a subscriber to each fixed-layout type on its own
    session: every one of the five types goes out, and none of them leaves its fixed-layout writer
    for rosbags' (`ENCODERS.fallbacks`: a regression in a writer is a failure here, not a slowdown)."""
    hot = sorted(WRITERS)
    seen: set[str] = set()
    options = BusOptions(listen=(endpoint(free_port()),), namespace=unique_namespace())
    config = ServerConfig(REPO / "worlds" / "empty.sdf", ROBOT_SDF, mode=Mode.LOCKSTEP)
    with Node(options, "server") as node:
        for typename in hot:
            dds = dds_type_name(typename)

            def saw(_sample: object, dds: str = dds) -> None:
                seen.add(dds)

            node.session.declare_subscriber(f"**/{dds}/**", saw)
        server = Server(config, node)
        try:
            node.refresh_subscribers()
            before = ENCODERS.fallbacks()
            for _ in range(round(0.2 / server.physics.step_size)):  # 0.2 s: every lidar's scan period (10 Hz) twice
                server.sim.step()
            wait_until(lambda: len(seen) == len(hot), 5.0, "a sample of each fixed-layout type")
            after = ENCODERS.fallbacks()
        finally:
            server.close()
    fell_back = {t: after.get(t, 0) - before.get(t, 0) for t in hot if after.get(t, 0) != before.get(t, 0)}
    assert fell_back == {}, f"fell back to rosbags' serializer: {fell_back}"
