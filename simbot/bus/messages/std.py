"""Stamps, headers and the one-value messages (builtin_interfaces, std_msgs, rosgraph_msgs).

Times are integer nanoseconds throughout, as the sim clock keeps them: no float rounding.
"""

from __future__ import annotations

from simbot.bus.messages.typestore import Clock, Empty, Float64, Header, String, Time

NS_PER_S = 1_000_000_000


def time_msg(ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds (nanosec always in [0, 1e9), as ROS does)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return Time(sec=sec, nanosec=nanosec)


def stamp_ns(stamp: Header | Time) -> int:
    """Integer nanoseconds of a Header's stamp or of a Time: the inverse of `time_msg`."""
    time = stamp.stamp if isinstance(stamp, Header) else stamp
    if not isinstance(time, Time):
        raise TypeError(f"stamp_ns takes a Header or a Time, not {type(stamp).__name__}")
    return int(time.sec) * NS_PER_S + int(time.nanosec)


def header(ns: int, frame_id: str) -> Header:
    """std_msgs/Header stamped `ns` in `frame_id`."""
    return Header(stamp=time_msg(ns), frame_id=frame_id)


def string(text: str) -> String:
    """std_msgs/String."""
    return String(data=text)


def empty() -> Empty:
    """std_msgs/Empty (one padding byte on the wire, as in every ROS 2 middleware)."""
    return Empty(structure_needs_at_least_one_member=0)


def float64(value: float) -> Float64:
    """std_msgs/Float64: a joint's target position, velocity or force."""
    return Float64(data=float(value))


def clock(ns: int) -> Clock:
    """rosgraph_msgs/Clock at `ns`."""
    return Clock(clock=time_msg(ns))
