"""What one ROS 2 robot publishes and where its LiDAR sits (paper Sec. V-E).

Topics (:class:`RosTopics`) default to a RealSense driver (``realsense2_camera`` with ``align_depth``; version 4
adds a ``/camera/camera`` namespace, pass its names), odometry on ``/odom`` and raw LiDAR returns on
``/livox/lidar`` (``livox_ros_driver2`` with ``xfer_format`` 0 publishes ``sensor_msgs/PointCloud2`` in the LiDAR's
own frame, which :class:`LidarMount` maps to the base frame). FAST-LIO2 publishes its LiDAR-inertial odometry on
``/Odometry`` (frame ``camera_init``): pass ``odometry="/Odometry"`` or remap it; its pose is the IMU's, taken as
the base's. Its ``/cloud_registered`` is not used as the scan: it lies in FAST-LIO2's world frame, not the base.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class RosTopics:
    """The topics of one robot (see the module docstring for the defaults); ``scan`` None: no LiDAR."""

    rgb: str = "/camera/color/image_raw"
    depth: str = "/camera/aligned_depth_to_color/image_raw"
    camera_info: str = "/camera/color/camera_info"
    odometry: str = "/odom"
    scan: str | None = "/livox/lidar"

    def __post_init__(self) -> None:
        names = [self.rgb, self.depth, self.camera_info, self.odometry, *([] if self.scan is None else [self.scan])]
        if not all(names) or len(set(names)) != len(names):
            raise ValueError(f"RosTopics must name distinct, non-empty topics, got {names}")


@dataclass(frozen=True)
class LidarMount:
    """Where the LiDAR sits on the base: position in metres (``z`` its height above the floor) and orientation
    in radians (roll, pitch, yaw about fixed x, y, z axes, as a ROS static transform; a LiDAR mounted upside down
    has ``roll = pi``)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    def to_base(self, points: ArrayLike) -> NDArray[np.float32]:
        """LiDAR-frame points (N, 3) to the base frame of :class:`SensorFrame` (``z`` from the floor)."""
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        cr, sr = math.cos(self.roll), math.sin(self.roll)
        rotation = np.array(
            [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ]
        )
        local = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        base: NDArray[np.float64] = local @ rotation.T + np.array([self.x, self.y, self.z])
        return base.astype(np.float32)
