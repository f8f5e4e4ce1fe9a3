"""CDR writers for the fixed-layout messages the server publishes at high rates, one struct.pack each.

rosbags' generic serializer walks a message field by field through a generated function per
nested type, after a separate pass that sizes it: several µs an Imu, and a hundred robots publish
thousands of these messages a sim second (issue 48; docs/speed.md, "CDR encoding", has the figures). Imu, Odometry, TFMessage,
Clock and LaserScan have one layout apart from their frame-id strings and float32 arrays, so each
is written here by a `struct.Struct` compiled once per frame-id length (the padding after a
string depends on it), their covariances and ranges copied as the arrays' raw bytes.

The bytes are rosbags' own (tests/test_bus_cdr_fast.py holds them equal), so nothing downstream
can tell. Only what rosbags would copy verbatim takes the fast road: a covariance or scan array
that is not a 1-D contiguous numpy array of the field's dtype and length, or any field that
struct refuses, makes a writer raise, and the encoder registry (`encoders`, `codec.ENCODERS`)
counts the fall-back and hands the message to rosbags, which writes the same bytes or raises the
error it always raised.
"""

from __future__ import annotations

from functools import lru_cache
from struct import Struct
from typing import Any

import numpy as np

from simbot.bus.encoders import Writer

ENCAPSULATION = b"\x00\x01\x00\x00"
"""CDR little-endian, options 0: the 4 bytes before every message (codec.CDR_LE and its options)."""
HEAD = "<4siI"
"""The encapsulation and a header's stamp (sec int32, nanosec uint32): where every writer starts."""
F64 = np.dtype(np.float64)
F32 = np.dtype(np.float32)
STRUCT_CACHE = 1024
"""Compiled layouts kept per writer: one per frame-id length (pair) seen, a handful per robot."""


class Unusual(Exception):
    """A field that rosbags would not copy verbatim: left to rosbags, for its bytes or its error."""


def string(offset: int, size: int, align: int) -> tuple[str, int]:
    """The struct format of a CDR string of `size` UTF-8 bytes whose length word lies at `offset`
    (4-aligned), NUL and padding included so that the next field is `align`-aligned; and that field's offset."""
    end = offset + 4 + size + 1
    pad = -end % align
    return f"I{size}s{1 + pad}x", end + pad


def raw(value: Any, dtype: np.dtype[Any], size: int | None = None) -> bytes:
    """The bytes of `value` if it is a 1-D contiguous numpy array of `dtype` (`size` long where the field
    is fixed): what rosbags copies verbatim. Anything else is Unusual. (`is`: numpy's builtin dtypes are
    singletons, and a dtype that is not the very one falls back, never to wrong bytes.)"""
    if type(value) is not np.ndarray or value.dtype is not dtype or value.ndim != 1 or not value.flags.c_contiguous:
        raise Unusual
    if size is not None and len(value) != size:
        raise Unusual
    return value.tobytes()


@lru_cache(maxsize=STRUCT_CACHE)
def imu_layout(frame: int) -> Struct:
    """sensor_msgs/Imu with a frame id of `frame` bytes: header, then 37 float64 (covariances as bytes)."""
    fmt, _ = string(8, frame, 8)
    return Struct(HEAD + fmt + "4d72s3d72s3d72s")


def imu(msg: Any) -> bytes:
    """sensor_msgs/Imu."""
    header, o, w, a = msg.header, msg.orientation, msg.angular_velocity, msg.linear_acceleration
    frame = header.frame_id.encode()
    return imu_layout(len(frame)).pack(
        ENCAPSULATION,
        header.stamp.sec,
        header.stamp.nanosec,
        len(frame) + 1,
        frame,
        o.x,
        o.y,
        o.z,
        o.w,
        raw(msg.orientation_covariance, F64, 9),
        w.x,
        w.y,
        w.z,
        raw(msg.angular_velocity_covariance, F64, 9),
        a.x,
        a.y,
        a.z,
        raw(msg.linear_acceleration_covariance, F64, 9),
    )


@lru_cache(maxsize=STRUCT_CACHE)
def stamped_pose_layout(start: int, frame: int, child: int) -> Struct:
    """A header, a child frame id and 7 float64 (position or translation, then rotation) from an offset
    ≡ `start` (mod 8), with frame ids of `frame` and `child` bytes: the padding before the float64 depends
    on all three. A TransformStamped is this; an Odometry begins with it (at 0)."""
    header, offset = string(start + 8, frame, 4)
    child_fmt, _ = string(offset, child, 8)
    return Struct("<iI" + header + child_fmt + "7d")


def stamped_pose(start: int, header: Any, child_frame_id: Any, position: Any, rotation: Any) -> bytes:
    """The bytes of a stamped pose (see `stamped_pose_layout`); they end 8-aligned."""
    frame, child = header.frame_id.encode(), child_frame_id.encode()
    return stamped_pose_layout(start, len(frame), len(child)).pack(
        header.stamp.sec,
        header.stamp.nanosec,
        len(frame) + 1,
        frame,
        len(child) + 1,
        child,
        position.x,
        position.y,
        position.z,
        rotation.x,
        rotation.y,
        rotation.z,
        rotation.w,
    )


COUNT = Struct("<I")
COVARIANCES_AND_TWIST = Struct("<288s6d288s")


def odometry(msg: Any) -> bytes:
    """nav_msgs/Odometry: the stamped pose, its covariance, the twist and its covariance (6×6 each)."""
    pose, twist = msg.pose, msg.twist
    v, w = twist.twist.linear, twist.twist.angular
    head = stamped_pose(0, msg.header, msg.child_frame_id, pose.pose.position, pose.pose.orientation)
    tail = COVARIANCES_AND_TWIST.pack(
        raw(pose.covariance, F64, 36), v.x, v.y, v.z, w.x, w.y, w.z, raw(twist.covariance, F64, 36)
    )
    return b"".join((ENCAPSULATION, head, tail))


def tf_message(msg: Any) -> bytes:
    """tf2_msgs/TFMessage: the count, then each transform (the first at offset 4, the others 8-aligned)."""
    transforms = msg.transforms
    parts = [ENCAPSULATION, COUNT.pack(len(transforms))]
    start = COUNT.size
    for stamped in transforms:
        transform = stamped.transform
        parts.append(
            stamped_pose(start, stamped.header, stamped.child_frame_id, transform.translation, transform.rotation)
        )
        start = 0
    return b"".join(parts)


CLOCK = Struct(HEAD)


def clock(msg: Any) -> bytes:
    """rosgraph_msgs/Clock."""
    return CLOCK.pack(ENCAPSULATION, msg.clock.sec, msg.clock.nanosec)


@lru_cache(maxsize=STRUCT_CACHE)
def laser_scan_layout(frame: int) -> Struct:
    """sensor_msgs/LaserScan up to its ranges' count, with a frame id of `frame` bytes."""
    header, _ = string(8, frame, 4)
    return Struct(HEAD + header + "7fI")


def laser_scan(msg: Any) -> bytes:
    """sensor_msgs/LaserScan: the fixed part packed, then the two float32 arrays' bytes."""
    header = msg.header
    frame = header.frame_id.encode()
    ranges, intensities = raw(msg.ranges, F32), raw(msg.intensities, F32)
    head = laser_scan_layout(len(frame)).pack(
        ENCAPSULATION,
        header.stamp.sec,
        header.stamp.nanosec,
        len(frame) + 1,
        frame,
        msg.angle_min,
        msg.angle_max,
        msg.angle_increment,
        msg.time_increment,
        msg.scan_time,
        msg.range_min,
        msg.range_max,
        len(ranges) // F32.itemsize,
    )
    return b"".join((head, ranges, COUNT.pack(len(intensities) // F32.itemsize), intensities))


WRITERS: dict[str, Writer] = {
    "sensor_msgs/msg/Imu": imu,
    "nav_msgs/msg/Odometry": odometry,
    "tf2_msgs/msg/TFMessage": tf_message,
    "rosgraph_msgs/msg/Clock": clock,
    "sensor_msgs/msg/LaserScan": laser_scan,
}
"""The writer of each fixed-layout type, by ROS 2 type name (a message's `__msgtype__`)."""
