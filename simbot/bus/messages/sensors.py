"""sensor_msgs of the one-reading sensors: joint states, laser scans, IMU, magnetometer, air
pressure and GPS (cameras' images are in images.py, point clouds in clouds.py)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simbot.bus.messages.geometry import quaternion_of, vector3
from simbot.bus.messages.std import header
from simbot.bus.messages.typestore import (
    FluidPressure,
    Imu,
    JointState,
    LaserScan,
    MagneticField,
    NavSatFix,
    NavSatStatus,
)
from simbot.bus.messages.values import Floats, diagonal, float_array, three


def joint_state(
    ns: int,
    names: Sequence[str],
    positions: Floats,
    velocities: Floats = (),
    efforts: Floats = (),
) -> JointState:
    """sensor_msgs/JointState; velocities and efforts may be empty (ROS allows it), else one per name."""
    position = float_array(positions, "positions")
    velocity = float_array(velocities, "velocities")
    effort = float_array(efforts, "efforts")
    if position.size != len(names):
        raise ValueError(f"joint_state: {position.size} positions for {len(names)} joints")
    for what, array in (("velocities", velocity), ("efforts", effort)):
        if array.size not in (0, len(names)):
            raise ValueError(f"joint_state: {array.size} {what} for {len(names)} joints (give one per joint or none)")
    return JointState(
        header=header(ns, ""),
        name=list(names),
        position=position,
        velocity=velocity,
        effort=effort,
    )


def _float32(value: float) -> float:
    """A float32 field's value as the wire carries it: a message handed over in process (simbot.bus.local)
    then reads as the same message after a CDR round trip."""
    return float(np.float32(value))


def laser_scan(
    ns: int,
    frame: str,
    angles: tuple[float, float, float],
    times: tuple[float, float],
    limits: tuple[float, float],
    ranges: Floats,
    intensities: Floats = (),
) -> LaserScan:
    """sensor_msgs/LaserScan: angles (min, max, increment), times (time_increment, scan_time), limits (range_min, range_max)."""
    angle_min, angle_max, increment = (_float32(a) for a in angles)
    time_increment, scan_time = (_float32(t) for t in times)
    range_min, range_max = (_float32(r) for r in limits)
    return LaserScan(
        header=header(ns, frame),
        angle_min=angle_min,
        angle_max=angle_max,
        angle_increment=increment,
        time_increment=time_increment,
        scan_time=scan_time,
        range_min=range_min,
        range_max=range_max,
        ranges=np.ascontiguousarray(ranges, dtype=np.float32).reshape(-1),
        intensities=np.ascontiguousarray(intensities, dtype=np.float32).reshape(-1),
    )


def imu(
    ns: int,
    frame: str,
    quat_xyzw: Floats,
    angular_xyz: Floats,
    linear_xyz: Floats,
    covariances: tuple[Floats, Floats, Floats] = ((0.0,) * 9, (0.0,) * 9, (0.0,) * 9),
) -> Imu:
    """sensor_msgs/Imu; covariances (orientation, angular velocity, linear acceleration), 3×3 row-major each."""
    orientation, angular, linear = (float_array(c, "imu covariance", 9) for c in covariances)
    return Imu(
        header=header(ns, frame),
        orientation=quaternion_of(quat_xyzw),
        orientation_covariance=orientation,
        angular_velocity=vector3(*three(angular_xyz, "angular velocity")),
        angular_velocity_covariance=angular,
        linear_acceleration=vector3(*three(linear_xyz, "linear acceleration")),
        linear_acceleration_covariance=linear,
    )


def magnetic_field(ns: int, frame: str, tesla_xyz: Floats, variances: Floats = (0.0, 0.0, 0.0)) -> MagneticField:
    """sensor_msgs/MagneticField in tesla, with each axis' variance on the covariance's diagonal (0: unknown)."""
    return MagneticField(
        header=header(ns, frame),
        magnetic_field=vector3(*three(tesla_xyz, "magnetic field")),
        magnetic_field_covariance=diagonal(variances),
    )


def fluid_pressure(ns: int, frame: str, pascal: float, variance: float = 0.0) -> FluidPressure:
    """sensor_msgs/FluidPressure in pascal (variance 0: unknown)."""
    return FluidPressure(header=header(ns, frame), fluid_pressure=float(pascal), variance=float(variance))


def nav_sat_fix(ns: int, frame: str, lat_lon_alt: Floats, variances: Floats | None = None) -> NavSatFix:
    """sensor_msgs/NavSatFix: a GPS fix at latitude and longitude (degrees) and altitude (metres above the
    WGS 84 ellipsoid); east, north and up variances when known (covariance type DIAGONAL_KNOWN), else UNKNOWN."""
    latitude, longitude, altitude = three(lat_lon_alt, "latitude, longitude, altitude")
    known = variances is not None
    return NavSatFix(
        header=header(ns, frame),
        status=NavSatStatus(status=NavSatStatus.STATUS_FIX, service=NavSatStatus.SERVICE_GPS),
        latitude=latitude,
        longitude=longitude,
        altitude=altitude,
        position_covariance=diagonal(variances if variances is not None else (0.0, 0.0, 0.0)),
        position_covariance_type=(
            NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN if known else NavSatFix.COVARIANCE_TYPE_UNKNOWN
        ),
    )
