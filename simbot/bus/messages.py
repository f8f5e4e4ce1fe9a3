"""Small constructors for the ROS 2 messages simbot sends, on the rosbags typestore classes.

They spell out the nesting once (an Odometry is six levels deep) so that the server and clients
write `odometry(ns, "odom", "base_footprint", xyz, quat, ...)`, and they convert inputs to what
the CDR serializer expects: Python floats, float64 numpy arrays for covariances and joint values.
Times are integer nanoseconds throughout, as the sim clock keeps them: no float rounding.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from rosbags.typesys.stores import ros2_humble as _ros

from simbot.bus.codec import TYPESTORE

# The typestore's own classes (codec.TYPESTORE holds the same ones), under their ROS names.
Time = _ros.builtin_interfaces__msg__Time
Point = _ros.geometry_msgs__msg__Point
Pose = _ros.geometry_msgs__msg__Pose
PoseStamped = _ros.geometry_msgs__msg__PoseStamped
PoseWithCovariance = _ros.geometry_msgs__msg__PoseWithCovariance
Quaternion = _ros.geometry_msgs__msg__Quaternion
Transform = _ros.geometry_msgs__msg__Transform
TransformStamped = _ros.geometry_msgs__msg__TransformStamped
Twist = _ros.geometry_msgs__msg__Twist
TwistWithCovariance = _ros.geometry_msgs__msg__TwistWithCovariance
Vector3 = _ros.geometry_msgs__msg__Vector3
Odometry = _ros.nav_msgs__msg__Odometry
Clock = _ros.rosgraph_msgs__msg__Clock
JointState = _ros.sensor_msgs__msg__JointState
Empty = _ros.std_msgs__msg__Empty
Float64 = _ros.std_msgs__msg__Float64
Header = _ros.std_msgs__msg__Header
CameraInfo = _ros.sensor_msgs__msg__CameraInfo
Image = _ros.sensor_msgs__msg__Image
Imu = _ros.sensor_msgs__msg__Imu
LaserScan = _ros.sensor_msgs__msg__LaserScan
PointCloud2 = _ros.sensor_msgs__msg__PointCloud2
PointField = _ros.sensor_msgs__msg__PointField
RegionOfInterest = _ros.sensor_msgs__msg__RegionOfInterest
String = _ros.std_msgs__msg__String
TFMessage = _ros.tf2_msgs__msg__TFMessage
FluidPressure = _ros.sensor_msgs__msg__FluidPressure
MagneticField = _ros.sensor_msgs__msg__MagneticField
NavSatFix = _ros.sensor_msgs__msg__NavSatFix
NavSatStatus = _ros.sensor_msgs__msg__NavSatStatus
UInt32 = _ros.std_msgs__msg__UInt32
Wrench = _ros.geometry_msgs__msg__Wrench
WrenchStamped = _ros.geometry_msgs__msg__WrenchStamped
# Gazebo's own (registered in codec.TYPESTORE)
Altimeter = TYPESTORE.types["ros_gz_interfaces/msg/Altimeter"]
Contact = TYPESTORE.types["ros_gz_interfaces/msg/Contact"]
Contacts = TYPESTORE.types["ros_gz_interfaces/msg/Contacts"]
Entity = TYPESTORE.types["ros_gz_interfaces/msg/Entity"]
JointWrench = TYPESTORE.types["ros_gz_interfaces/msg/JointWrench"]

__all__ = [
    "Altimeter",
    "CameraInfo",
    "Clock",
    "ContactPair",
    "Contacts",
    "Empty",
    "Float64",
    "Header",
    "Image",
    "FluidPressure",
    "Imu",
    "JointState",
    "LaserScan",
    "MagneticField",
    "NavSatFix",
    "Odometry",
    "PointCloud2",
    "PointField",
    "PoseStamped",
    "String",
    "TFMessage",
    "Time",
    "TransformStamped",
    "Twist",
    "Vector3",
    "WrenchStamped",
    "altimeter",
    "camera_info",
    "clock",
    "contacts",
    "depth_image",
    "depth_pixels",
    "empty",
    "fluid_pressure",
    "header",
    "image",
    "image_pixels",
    "imu",
    "joint_state",
    "laser_scan",
    "lidar_points",
    "lidar_points_array",
    "magnetic_field",
    "nav_sat_fix",
    "odometry",
    "point_cloud",
    "point_cloud_array",
    "pose_stamped",
    "quaternion",
    "stamp_ns",
    "string",
    "tf_message",
    "time_msg",
    "transform_stamped",
    "twist",
    "vector3",
    "wrench_stamped",
]

NS_PER_S = 1_000_000_000
COVARIANCE_SIZE = 36

Floats = Sequence[float] | npt.NDArray[np.floating[Any]]


def _three(values: Floats, what: str) -> tuple[float, float, float]:
    x, y, z = _floats(values, 3, what)
    return x, y, z


def _floats(values: Floats, size: int, what: str) -> list[float]:
    result = [float(v) for v in values]
    if len(result) != size:
        raise ValueError(f"{what}: expected {size} values, got {len(result)}")
    return result


def _float_array(values: Floats, what: str, size: int | None = None) -> npt.NDArray[np.float64]:
    array = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
    if size is not None and array.size != size:
        raise ValueError(f"{what}: expected {size} values, got {array.size}")
    return array


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


def vector3(x: float, y: float, z: float) -> Vector3:
    """geometry_msgs/Vector3."""
    return Vector3(x=float(x), y=float(y), z=float(z))


def quaternion(x: float, y: float, z: float, w: float) -> Quaternion:
    """geometry_msgs/Quaternion, in ROS order x, y, z, w."""
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def _quaternion(quat_xyzw: Floats) -> Quaternion:
    return quaternion(*_floats(quat_xyzw, 4, "quaternion (x, y, z, w)"))


def transform_stamped(ns: int, parent: str, child: str, xyz: Floats, quat_xyzw: Floats) -> TransformStamped:
    """geometry_msgs/TransformStamped: the pose of `child` in `parent`."""
    translation = vector3(*_three(xyz, "translation"))
    return TransformStamped(
        header=header(ns, parent),
        child_frame_id=child,
        transform=Transform(translation=translation, rotation=_quaternion(quat_xyzw)),
    )


def tf_message(transforms: Iterable[TransformStamped]) -> TFMessage:
    """tf2_msgs/TFMessage holding `transforms`."""
    return TFMessage(transforms=list(transforms))


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


def twist(linear_xyz: Floats = (0.0, 0.0, 0.0), angular_xyz: Floats = (0.0, 0.0, 0.0)) -> Twist:
    """geometry_msgs/Twist; no arguments is a stop."""
    return Twist(linear=vector3(*_three(linear_xyz, "linear")), angular=vector3(*_three(angular_xyz, "angular")))


def _pose(xyz: Floats, quat_xyzw: Floats) -> Pose:
    x, y, z = _three(xyz, "position")
    return Pose(position=Point(x=x, y=y, z=z), orientation=_quaternion(quat_xyzw))


def pose_stamped(ns: int, frame: str, xyz: Floats, quat_xyzw: Floats) -> PoseStamped:
    """geometry_msgs/PoseStamped in `frame`."""
    return PoseStamped(header=header(ns, frame), pose=_pose(xyz, quat_xyzw))


def odometry(
    ns: int,
    frame_id: str,
    child_frame_id: str,
    xyz: Floats,
    quat_xyzw: Floats,
    linear_xyz: Floats,
    angular_xyz: Floats,
    pose_covariance: Floats = (0.0,) * COVARIANCE_SIZE,
    twist_covariance: Floats = (0.0,) * COVARIANCE_SIZE,
) -> Odometry:
    """nav_msgs/Odometry: pose in `frame_id`, twist in `child_frame_id`, 6×6 row-major covariances."""
    return Odometry(
        header=header(ns, frame_id),
        child_frame_id=child_frame_id,
        pose=PoseWithCovariance(
            pose=_pose(xyz, quat_xyzw),
            covariance=_float_array(pose_covariance, "pose covariance", COVARIANCE_SIZE),
        ),
        twist=TwistWithCovariance(
            twist=twist(linear_xyz, angular_xyz),
            covariance=_float_array(twist_covariance, "twist covariance", COVARIANCE_SIZE),
        ),
    )


def joint_state(
    ns: int,
    names: Sequence[str],
    positions: Floats,
    velocities: Floats = (),
    efforts: Floats = (),
) -> JointState:
    """sensor_msgs/JointState; velocities and efforts may be empty (ROS allows it), else one per name."""
    position = _float_array(positions, "positions")
    velocity = _float_array(velocities, "velocities")
    effort = _float_array(efforts, "efforts")
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
    angle_min, angle_max, increment = (float(a) for a in angles)
    time_increment, scan_time = (float(t) for t in times)
    range_min, range_max = (float(r) for r in limits)
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
    orientation, angular, linear = (_float_array(c, "imu covariance", 9) for c in covariances)
    return Imu(
        header=header(ns, frame),
        orientation=_quaternion(quat_xyzw),
        orientation_covariance=orientation,
        angular_velocity=vector3(*_three(angular_xyz, "angular velocity")),
        angular_velocity_covariance=angular,
        linear_acceleration=vector3(*_three(linear_xyz, "linear acceleration")),
        linear_acceleration_covariance=linear,
    )


IMAGE_ENCODINGS = {3: "rgb8", 1: "mono8"}
"""sensor_msgs/image_encodings by channels of uint8 pixels."""


def image(ns: int, frame: str, pixels: npt.NDArray[np.uint8]) -> Image:
    """sensor_msgs/Image from an H×W×3 (rgb8) or H×W (mono8) uint8 array; the bytes are copied once."""
    if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3):
        raise ValueError(f"image: expected H×W or H×W×3 uint8 pixels, got {pixels.dtype} {pixels.shape}")
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    if channels not in IMAGE_ENCODINGS:
        raise ValueError(f"image: {channels} channels; expected 1 or 3")
    height, width = pixels.shape[:2]
    return Image(
        header=header(ns, frame),
        height=height,
        width=width,
        encoding=IMAGE_ENCODINGS[channels],
        is_bigendian=0,
        step=width * channels,
        data=np.ascontiguousarray(pixels).reshape(-1).copy(),
    )


def depth_image(ns: int, frame: str, depth: npt.NDArray[np.float32]) -> Image:
    """sensor_msgs/Image `32FC1` (REP 118: metres along the optical axis, ±inf out of range) from an H×W float32 array."""
    if depth.dtype != np.float32 or depth.ndim != 2:
        raise ValueError(f"depth image: expected H×W float32, got {depth.dtype} {depth.shape}")
    height, width = depth.shape
    return Image(
        header=header(ns, frame),
        height=height,
        width=width,
        encoding="32FC1",
        is_bigendian=0,
        step=width * 4,
        data=np.ascontiguousarray(depth).reshape(-1).view(np.uint8).copy(),
    )


def depth_pixels(msg: Image) -> npt.NDArray[np.float32]:
    """The H×W float32 metres of a `32FC1` Image (the inverse of `depth_image`)."""
    if msg.encoding != "32FC1":
        raise ValueError(f"encoding {msg.encoding!r} is not 32FC1")
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < width * 4 or data.size < step * height:
        raise ValueError(f"{data.size} bytes with step {step} cannot hold {height} rows of {width} 32FC1 pixels")
    rows = data[: step * height].reshape(height, step)[:, : width * 4]
    return np.ascontiguousarray(rows).view(np.float32).reshape(height, width)


POINT_FIELDS = ("x", "y", "z", "rgb")
"""An organised cloud's fields, float32 each; rgb packs 0x00RRGGBB into the float's bits (PCL's convention)."""


def point_cloud(ns: int, frame: str, points: npt.NDArray[np.float32]) -> PointCloud2:
    """sensor_msgs/PointCloud2, organised (H×W), from H×W×4 float32 x y z rgb; NaN marks no point."""
    if points.dtype != np.float32 or points.ndim != 3 or points.shape[2] != len(POINT_FIELDS):
        raise ValueError(f"point cloud: expected H×W×4 float32, got {points.dtype} {points.shape}")
    height, width = points.shape[:2]
    fields = [
        PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, name in enumerate(POINT_FIELDS)
    ]
    return PointCloud2(
        header=header(ns, frame),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=16,
        row_step=16 * width,
        data=np.ascontiguousarray(points).reshape(-1).view(np.uint8).copy(),
        is_dense=False,
    )


def point_cloud_array(msg: PointCloud2) -> npt.NDArray[np.float32]:
    """H×W×4 float32 x y z rgb of a cloud `point_cloud` made (the inverse of `point_cloud`)."""
    names = tuple(f.name for f in msg.fields)
    if names != POINT_FIELDS or int(msg.point_step) != 16:
        raise ValueError(
            f"fields {names} with point step {msg.point_step}: expected {POINT_FIELDS} float32 at 16 bytes"
        )
    data = np.asarray(msg.data, dtype=np.uint8)
    return np.ascontiguousarray(data).view(np.float32).reshape(int(msg.height), int(msg.width), 4)


CHANNELS_OF = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
"""The uint8 sensor_msgs/image_encodings a client can read, by their channels."""


def image_pixels(msg: Image) -> npt.NDArray[np.uint8]:
    """The pixels of a sensor_msgs/Image: H×W×C uint8 (H×W for mono8), its row padding (step) dropped.

    The inverse of `image`. ValueError, one line, for an encoding not in CHANNELS_OF or data
    too short for height × step.
    """
    channels = CHANNELS_OF.get(msg.encoding)
    if channels is None:
        raise ValueError(f"encoding {msg.encoding!r} is not one of {', '.join(CHANNELS_OF)}")
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < width * channels or data.size < step * height:
        raise ValueError(
            f"{data.size} bytes with step {step} cannot hold {height} rows of {width} {msg.encoding} pixels"
        )
    rows = data[: step * height].reshape(height, step)[:, : width * channels]
    return rows if channels == 1 else rows.reshape(height, width, channels)


def camera_info(ns: int, frame: str, width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> CameraInfo:
    """sensor_msgs/CameraInfo of an ideal pinhole camera (no distortion, identity rectification)."""
    k = (fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0)
    p = (fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0)
    return CameraInfo(
        header=header(ns, frame),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=np.zeros(5, dtype=np.float64),
        k=_float_array(k, "K", 9),
        r=_float_array((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), "R", 9),
        p=_float_array(p, "P", 12),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


LIDAR_POINT_FIELDS = (
    ("x", 0, PointField.FLOAT32),
    ("y", 4, PointField.FLOAT32),
    ("z", 8, PointField.FLOAT32),
    ("intensity", 12, PointField.FLOAT32),
    ("ring", 16, PointField.UINT16),
)
"""A lidar's cloud as Gazebo's gpu_lidar packs it: x y z intensity float32, ring uint16, 18 bytes a point, unaligned."""
LIDAR_POINT_DTYPE = np.dtype(
    {"names": ["x", "y", "z", "intensity", "ring"], "formats": ["<f4"] * 4 + ["<u2"], "offsets": [0, 4, 8, 12, 16]}
)


def lidar_points(ns: int, frame: str, xyz: npt.NDArray[np.floating[Any]], intensity: Floats = ()) -> PointCloud2:
    """sensor_msgs/PointCloud2 of a 3-D lidar, organised V×H (a row per vertical angle, its ring number);
    NaN coordinates where a ray returned nothing; intensity 0 where none is given."""
    if xyz.ndim != 3 or xyz.shape[2] != 3:
        raise ValueError(f"lidar points: expected V×H×3 coordinates, got {xyz.shape}")
    rows, columns = xyz.shape[:2]
    points = np.zeros((rows, columns), dtype=LIDAR_POINT_DTYPE)
    for i, axis in enumerate("xyz"):
        points[axis] = xyz[:, :, i]
    if len(intensity):
        points["intensity"] = np.asarray(intensity, dtype=np.float32).reshape(rows, columns)
    points["ring"] = np.arange(rows, dtype=np.uint16)[:, None]
    return PointCloud2(
        header=header(ns, frame),
        height=rows,
        width=columns,
        fields=[PointField(name=n, offset=o, datatype=t, count=1) for n, o, t in LIDAR_POINT_FIELDS],
        is_bigendian=False,
        point_step=LIDAR_POINT_DTYPE.itemsize,
        row_step=LIDAR_POINT_DTYPE.itemsize * columns,
        data=points.reshape(-1).view(np.uint8).copy(),
        is_dense=bool(np.isfinite(xyz).all()),
    )


def lidar_points_array(msg: PointCloud2) -> npt.NDArray[np.void]:
    """The V×H structured array (x, y, z, intensity, ring) of a cloud `lidar_points` made (its inverse)."""
    fields = tuple((f.name, int(f.offset), int(f.datatype)) for f in msg.fields)
    if fields != LIDAR_POINT_FIELDS or int(msg.point_step) != LIDAR_POINT_DTYPE.itemsize:
        raise ValueError(f"fields {fields} with point step {msg.point_step}: not a lidar cloud {LIDAR_POINT_FIELDS}")
    data = np.ascontiguousarray(np.asarray(msg.data, dtype=np.uint8))
    return data.view(LIDAR_POINT_DTYPE).reshape(int(msg.height), int(msg.width))


def _diagonal(variances: Floats) -> npt.NDArray[np.float64]:
    return np.diag(_float_array(variances, "variances", 3)).reshape(-1)


def magnetic_field(ns: int, frame: str, tesla_xyz: Floats, variances: Floats = (0.0, 0.0, 0.0)) -> MagneticField:
    """sensor_msgs/MagneticField in tesla, with each axis' variance on the covariance's diagonal (0: unknown)."""
    return MagneticField(
        header=header(ns, frame),
        magnetic_field=vector3(*_three(tesla_xyz, "magnetic field")),
        magnetic_field_covariance=_diagonal(variances),
    )


def fluid_pressure(ns: int, frame: str, pascal: float, variance: float = 0.0) -> FluidPressure:
    """sensor_msgs/FluidPressure in pascal (variance 0: unknown)."""
    return FluidPressure(header=header(ns, frame), fluid_pressure=float(pascal), variance=float(variance))


def nav_sat_fix(ns: int, frame: str, lat_lon_alt: Floats, variances: Floats | None = None) -> NavSatFix:
    """sensor_msgs/NavSatFix: a GPS fix at latitude and longitude (degrees) and altitude (metres above the
    WGS 84 ellipsoid); east, north and up variances when known (covariance type DIAGONAL_KNOWN), else UNKNOWN."""
    latitude, longitude, altitude = _three(lat_lon_alt, "latitude, longitude, altitude")
    known = variances is not None
    return NavSatFix(
        header=header(ns, frame),
        status=NavSatStatus(status=NavSatStatus.STATUS_FIX, service=NavSatStatus.SERVICE_GPS),
        latitude=latitude,
        longitude=longitude,
        altitude=altitude,
        position_covariance=_diagonal(variances if variances is not None else (0.0, 0.0, 0.0)),
        position_covariance_type=(
            NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN if known else NavSatFix.COVARIANCE_TYPE_UNKNOWN
        ),
    )


def _wrench(force_xyz: Floats, torque_xyz: Floats) -> Wrench:
    return Wrench(force=vector3(*_three(force_xyz, "force")), torque=vector3(*_three(torque_xyz, "torque")))


def wrench_stamped(ns: int, frame: str, force_xyz: Floats, torque_xyz: Floats) -> WrenchStamped:
    """geometry_msgs/WrenchStamped: newtons and newton-metres."""
    return WrenchStamped(header=header(ns, frame), wrench=_wrench(force_xyz, torque_xyz))


def altimeter(ns: int, frame: str, position: float, velocity: float, reference: float) -> Any:
    """ros_gz_interfaces/Altimeter: height over the reference and vertical velocity (m, m/s), the reference (m)."""
    return Altimeter(
        header=header(ns, frame),
        vertical_position=float(position),
        vertical_velocity=float(velocity),
        vertical_reference=float(reference),
    )


@dataclass(frozen=True)
class ContactPair:
    """Where two collisions touch: the points (world), normals (unit, pushing collision1 away from
    collision2), penetration depths, and the force on collision1 at each point (N)."""

    collision1: str
    collision2: str
    positions: Sequence[Floats]
    normals: Sequence[Floats]
    depths: Sequence[float]
    forces: Sequence[Floats]


def contacts(ns: int, frame: str, pairs: Iterable[ContactPair]) -> Any:
    """ros_gz_interfaces/Contacts as ros_gz_bridge writes Gazebo's: a Contact per pair of collisions
    (scoped names `model::link::collision`), a JointWrench per point (body 2's wrench the opposite)."""
    stamp = header(ns, frame)
    entity_type = Entity.COLLISION
    return Contacts(
        header=stamp,
        contacts=[
            Contact(
                collision1=Entity(id=0, name=pair.collision1, type=entity_type),
                collision2=Entity(id=0, name=pair.collision2, type=entity_type),
                positions=[vector3(*_three(p, "contact position")) for p in pair.positions],
                normals=[vector3(*_three(n, "contact normal")) for n in pair.normals],
                depths=_float_array(pair.depths, "depths"),
                wrenches=[_joint_wrench(stamp, pair, force) for force in pair.forces],
            )
            for pair in pairs
        ],
    )


def _joint_wrench(stamp: Header, pair: ContactPair, force: Floats) -> Any:
    on_1 = np.asarray(_three(force, "contact force"))
    none = (0.0, 0.0, 0.0)
    return JointWrench(
        header=stamp,
        body_1_name=String(data=pair.collision1),
        body_1_id=UInt32(data=0),
        body_2_name=String(data=pair.collision2),
        body_2_id=UInt32(data=0),
        body_1_wrench=_wrench(on_1, none),
        body_2_wrench=_wrench(-on_1, none),
    )
