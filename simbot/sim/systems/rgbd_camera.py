"""RGBD camera (SDF `rgbd_camera`, also `rgbd`): colour, depth and an organised point cloud from
one render, as Gazebo's RGBD camera publishes them under its topic (`<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>`):

| key | type |
| --- | --- |
| `<topic>/image` | sensor_msgs/Image, rgb8 (or mono8 by `<format>`) |
| `<topic>/depth_image` | sensor_msgs/Image, 32FC1 metres along the optical axis (REP 118) |
| `<topic>/points` | sensor_msgs/PointCloud2, H×W, fields x y z rgb (float32, rgb packed 0x00RRGGBB), optical frame, NaN where no surface |
| `<topic>/camera_info` | sensor_msgs/CameraInfo |

All four share one stamp. The SDF parameters are the camera's (`camera.py`). Through a
`<distortion>` lens the image and depth are bent alike and each point lies along its pixel's
undistorted ray, so the cloud stays metric (simbot/sim/render/lens.py).
"""

from __future__ import annotations

from simbot.sim.systems.camera import POINT_CLOUD, Camera, Product


class RgbdCamera(Camera):
    """Image, depth image and points under `<topic>/`, with camera_info."""

    products = (Product("image", "color"), Product("depth_image", "depth"), Product("points", "points", POINT_CLOUD))
    kind = ""
    """Gazebo's default key of an RGBD camera is the sensor's scoped name; its products lie under it."""

    def info_key(self, topic: str) -> str:
        return f"{topic}/camera_info"
