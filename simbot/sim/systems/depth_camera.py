"""Depth camera (SDF `depth_camera`, also `depth`): a `32FC1` sensor_msgs/Image of metres along
the optical axis (REP 118: z-depth, so a wall square to the axis reads one value everywhere; +inf
where nothing lies within the far clip; never −inf: geometry nearer than the near clip is cut
away, as in Gazebo, so a camera inside its housing sees out).

The same camera as `camera` (its SDF parameters, its camera_info beside the image key, Gazebo's
sibling `camera_info`), rendering depth only; `<image><format>` is ignored. Pixel noise is not
applied to depth. A `<distortion>` bends the depth image as it bends a colour one
(simbot/sim/render/lens.py), taking the nearest rendered depth so that none is invented across an
edge; +inf where the lens brings no ray.
"""

from __future__ import annotations

from simbot.sim.systems.camera import Camera, Product


class DepthCamera(Camera):
    """sensor_msgs/Image (32FC1) on `<topic>` and CameraInfo beside it."""

    products = (Product("", "depth"),)
    kind = "depth_image"
