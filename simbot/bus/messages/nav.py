"""nav_msgs: the odometry of a drive (its pose and twist, each with a covariance), and a map's occupancy grid."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from simbot.bus.messages.geometry import pose, twist
from simbot.bus.messages.std import header, time_msg
from simbot.bus.messages.typestore import MapMetaData, OccupancyGrid, Odometry, PoseWithCovariance, TwistWithCovariance
from simbot.bus.messages.values import Floats, float_array

COVARIANCE_SIZE = 36


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
            pose=pose(xyz, quat_xyzw),
            covariance=float_array(pose_covariance, "pose covariance", COVARIANCE_SIZE),
        ),
        twist=TwistWithCovariance(
            twist=twist(linear_xyz, angular_xyz),
            covariance=float_array(twist_covariance, "twist covariance", COVARIANCE_SIZE),
        ),
    )


def occupancy_grid(
    ns: int, frame_id: str, resolution: float, origin_xyz: Floats, cells: npt.NDArray[np.int8]
) -> OccupancyGrid:
    """nav_msgs/OccupancyGrid of `cells` (rows × columns: row 0 at the origin, along y; 0 free, 100
    occupied, −1 unknown), its origin cell's corner at `origin_xyz` in `frame_id`, unturned; loaded at `ns`."""
    height, width = cells.shape
    info = MapMetaData(
        map_load_time=time_msg(ns),
        resolution=float(resolution),
        width=width,
        height=height,
        origin=pose(origin_xyz, (0.0, 0.0, 0.0, 1.0)),
    )
    data = np.ascontiguousarray(cells, dtype=np.int8).reshape(-1)
    return OccupancyGrid(header=header(ns, frame_id), info=info, data=data)
