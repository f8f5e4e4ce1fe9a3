"""The message classes simbot builds, looked up once in codec.TYPESTORE under their ROS names.

The constructor modules take their classes from here, so that a message type simbot starts to
publish is named in one place (and, when ROS 2 Humble lacks it, registered in codec.py).
"""

from __future__ import annotations

from rosbags.typesys.stores import ros2_humble as _ros

from simbot.bus.codec import TYPESTORE

# builtin_interfaces, std_msgs, rosgraph_msgs
Time = _ros.builtin_interfaces__msg__Time
Clock = _ros.rosgraph_msgs__msg__Clock
Empty = _ros.std_msgs__msg__Empty
Float64 = _ros.std_msgs__msg__Float64
Header = _ros.std_msgs__msg__Header
String = _ros.std_msgs__msg__String
UInt32 = _ros.std_msgs__msg__UInt32
# geometry_msgs, tf2_msgs
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
Wrench = _ros.geometry_msgs__msg__Wrench
WrenchStamped = _ros.geometry_msgs__msg__WrenchStamped
TFMessage = _ros.tf2_msgs__msg__TFMessage
# nav_msgs
Odometry = _ros.nav_msgs__msg__Odometry
MapMetaData = _ros.nav_msgs__msg__MapMetaData
OccupancyGrid = _ros.nav_msgs__msg__OccupancyGrid
# sensor_msgs
CameraInfo = _ros.sensor_msgs__msg__CameraInfo
FluidPressure = _ros.sensor_msgs__msg__FluidPressure
Image = _ros.sensor_msgs__msg__Image
Imu = _ros.sensor_msgs__msg__Imu
JointState = _ros.sensor_msgs__msg__JointState
LaserScan = _ros.sensor_msgs__msg__LaserScan
MagneticField = _ros.sensor_msgs__msg__MagneticField
NavSatFix = _ros.sensor_msgs__msg__NavSatFix
NavSatStatus = _ros.sensor_msgs__msg__NavSatStatus
PointCloud2 = _ros.sensor_msgs__msg__PointCloud2
PointField = _ros.sensor_msgs__msg__PointField
RegionOfInterest = _ros.sensor_msgs__msg__RegionOfInterest
# Gazebo's own (registered in codec.TYPESTORE)
Altimeter = TYPESTORE.types["ros_gz_interfaces/msg/Altimeter"]
Contact = TYPESTORE.types["ros_gz_interfaces/msg/Contact"]
Contacts = TYPESTORE.types["ros_gz_interfaces/msg/Contacts"]
Entity = TYPESTORE.types["ros_gz_interfaces/msg/Entity"]
JointWrench = TYPESTORE.types["ros_gz_interfaces/msg/JointWrench"]
# vision_msgs (registered in codec.TYPESTORE): the bounding-box camera's detections
BoundingBox2D = TYPESTORE.types["vision_msgs/msg/BoundingBox2D"]
BoundingBox3D = TYPESTORE.types["vision_msgs/msg/BoundingBox3D"]
Detection2D = TYPESTORE.types["vision_msgs/msg/Detection2D"]
Detection2DArray = TYPESTORE.types["vision_msgs/msg/Detection2DArray"]
Detection3D = TYPESTORE.types["vision_msgs/msg/Detection3D"]
Detection3DArray = TYPESTORE.types["vision_msgs/msg/Detection3DArray"]
ObjectHypothesis = TYPESTORE.types["vision_msgs/msg/ObjectHypothesis"]
ObjectHypothesisWithPose = TYPESTORE.types["vision_msgs/msg/ObjectHypothesisWithPose"]
Point2D = TYPESTORE.types["vision_msgs/msg/Point2D"]
Pose2D = TYPESTORE.types["vision_msgs/msg/Pose2D"]
# visualization_msgs (the scene for viewers)
ColorRGBA = _ros.std_msgs__msg__ColorRGBA
Marker = _ros.visualization_msgs__msg__Marker
MarkerArray = _ros.visualization_msgs__msg__MarkerArray
MeshFile = _ros.visualization_msgs__msg__MeshFile
CompressedImage = _ros.sensor_msgs__msg__CompressedImage
Duration = _ros.builtin_interfaces__msg__Duration
