"""RGBD camera (SDF `rgbd_camera`, also `rgbd`): colour, depth and an organised point cloud from
one render, as Gazebo's RGBD camera publishes them under its topic (`<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>`):

| key | type |
| --- | --- |
| `<topic>/image` | sensor_msgs/Image, rgb8 (or mono8 by `<format>`) |
| `<topic>/depth_image` | sensor_msgs/Image, 32FC1 metres along the optical axis (REP 118) |
| `<topic>/points` | sensor_msgs/PointCloud2, H×W, fields x y z rgb (float32, rgb packed 0x00RRGGBB), optical frame, NaN where no surface |
| `<topic>/camera_info` | sensor_msgs/CameraInfo |

All four share one stamp. The SDF parameters are the camera's (`camera.py`).
"""

from __future__ import annotations

from simbot.bus import messages
from simbot.sim.bus_view import SimBus
from simbot.sim.systems.camera import Camera, Output


class RgbdCamera(Camera):
    """Image, depth image and points under `<topic>/`, with camera_info."""

    depth = True
    color = True
    kind = ""
    """Gazebo's default key of an RGBD camera is the sensor's scoped name; its products lie under it."""

    def advertise(self, bus: SimBus, topic: str) -> list[Output]:
        frame = self.frame_id
        return [
            Output(
                bus.publisher(f"{topic}/image", messages.Image), lambda f: messages.image(f.stamp_ns, frame, f.rgb())
            ),
            Output(
                bus.publisher(f"{topic}/depth_image", messages.Image),
                lambda f: messages.depth_image(f.stamp_ns, frame, f.metres()),
            ),
            Output(
                bus.publisher(f"{topic}/points", messages.PointCloud2),
                lambda f: messages.point_cloud(f.stamp_ns, frame, f.cloud()),
            ),
        ]

    def info_key(self, topic: str) -> str:
        return f"{topic}/camera_info"
