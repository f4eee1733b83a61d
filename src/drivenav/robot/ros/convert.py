"""ROS 2 messages to arrays and poses (paper Sec. V-E): images, camera intrinsics, odometry and point clouds, read
by attribute so that ``rosbags``' deserialised messages and ``rclpy``'s alike convert, without ``rclpy`` installed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.types import CameraIntrinsics, Pose

RosMessage = Any
"""A ROS 2 message object, read by attribute (``rosbags``' dataclasses and ``rclpy``'s classes alike)."""

_FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
_COLOUR_ENCODINGS = ("rgb8", "bgr8")
_DEPTH_ENCODINGS = ("16UC1", "32FC1")
_IMAGE_LAYOUTS = {"rgb8": ("u1", 3), "bgr8": ("u1", 3), "16UC1": ("u2", 1), "32FC1": ("f4", 1)}


def stamp_seconds(header: RosMessage) -> float:
    """A ``std_msgs/Header``'s stamp in seconds."""
    return float(header.stamp.sec) + float(header.stamp.nanosec) * 1e-9


def image_to_array(msg: RosMessage) -> NDArray[np.uint8] | NDArray[np.float32]:
    """A ``sensor_msgs/Image``: rgb8 / bgr8 as (H, W, 3) RGB uint8 (:func:`image_to_rgb`), 16UC1 / 32FC1 as
    (H, W) float32 metres (:func:`image_to_depth`)."""
    if msg.encoding not in _IMAGE_LAYOUTS:
        raise ValueError(f"unsupported image encoding {msg.encoding!r}; expected one of {sorted(_IMAGE_LAYOUTS)}")
    return image_to_rgb(msg) if msg.encoding in _COLOUR_ENCODINGS else image_to_depth(msg)


def image_to_rgb(msg: RosMessage) -> NDArray[np.uint8]:
    """An rgb8 or bgr8 ``sensor_msgs/Image`` as (H, W, 3) RGB uint8."""
    if msg.encoding not in _COLOUR_ENCODINGS:
        raise ValueError(f"expected a colour image (rgb8 or bgr8), got encoding {msg.encoding!r}")
    pixels = _pixels(msg)
    rgb = pixels[:, :, ::-1] if msg.encoding == "bgr8" else pixels
    return np.ascontiguousarray(rgb, dtype=np.uint8)


def image_to_depth(msg: RosMessage) -> NDArray[np.float32]:
    """A depth ``sensor_msgs/Image`` as (H, W) float32 metres, NaN where there is no return: 16UC1 holds
    millimetres (0 = no return), 32FC1 metres (non-finite or <= 0 = no return)."""
    if msg.encoding not in _DEPTH_ENCODINGS:
        raise ValueError(f"expected a depth image (16UC1 or 32FC1), got encoding {msg.encoding!r}")
    raw = _pixels(msg)[:, :, 0]
    depth: NDArray[np.float32] = raw.astype(np.float32)
    if msg.encoding == "16UC1":
        depth /= np.float32(1000.0)
        depth[raw == 0] = np.nan
    else:
        depth[~np.isfinite(depth) | (depth <= 0.0)] = np.nan
    return depth


def _pixels(msg: RosMessage) -> NDArray[Any]:
    """The (H, W, C) pixels of an image in native byte order, honouring ``step`` (row padding) and
    ``is_bigendian``; ``msg.encoding`` is one of ``_IMAGE_LAYOUTS``."""
    kind, channels = _IMAGE_LAYOUTS[msg.encoding]
    dtype = np.dtype((">" if msg.is_bigendian else "<") + kind)
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    rows = _rows(msg.data, height, step, width * channels * dtype.itemsize, "image")
    return rows.view(dtype).astype(dtype.newbyteorder("=")).reshape(height, width, channels)


def _rows(data: Any, height: int, step: int, used: int, what: str) -> NDArray[np.uint8]:
    """The first ``used`` bytes of each of ``height`` rows of ``step`` bytes, contiguous."""
    buffer = np.frombuffer(data, dtype=np.uint8)
    if step < used or buffer.size < height * step:
        raise ValueError(f"{what} data too short: {buffer.size} bytes for {height} rows of {step} (>= {used})")
    return np.ascontiguousarray(buffer[: height * step].reshape(height, step)[:, :used])


def camera_info_to_intrinsics(msg: RosMessage) -> CameraIntrinsics:
    """A ``sensor_msgs/CameraInfo``'s pinhole intrinsics (``k`` = [fx 0 cx; 0 fy cy; 0 0 1])."""
    k = [float(v) for v in msg.k]
    if k[0] <= 0.0 or k[4] <= 0.0:
        raise ValueError(f"camera_info has no focal length (k = {k}): is the camera calibrated?")
    return CameraIntrinsics(int(msg.width), int(msg.height), k[0], k[4], k[2], k[5])


def odometry_to_pose(msg: RosMessage) -> Pose:
    """A ``nav_msgs/Odometry``'s pose: position x, y, the yaw of its orientation quaternion, and the height
    position z (0 from a planar odometry; a 3-D one, LiDAR-inertial for instance, tells the floors apart)."""
    position, q = msg.pose.pose.position, msg.pose.pose.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return Pose(float(position.x), float(position.y), yaw, float(position.z))


def pointcloud2_to_xyz(msg: RosMessage) -> NDArray[np.float32]:
    """A ``sensor_msgs/PointCloud2``'s FLOAT32 fields x, y, z as (N, 3) float32, honouring ``point_step``,
    ``row_step`` and ``is_bigendian``; points with a non-finite coordinate are dropped."""
    by_name = {field.name: field for field in msg.fields}
    point_step = int(msg.point_step)
    for name in ("x", "y", "z"):
        field = by_name.get(name)
        if field is None or field.datatype != _FLOAT32 or field.offset + 4 > point_step:
            raise ValueError(f"point cloud field {name!r} must be FLOAT32 within point_step, got {field}")
    order = ">" if msg.is_bigendian else "<"
    dtype = np.dtype(
        {
            "names": ["x", "y", "z"],
            "formats": [order + "f4"] * 3,
            "offsets": [int(by_name[name].offset) for name in ("x", "y", "z")],
            "itemsize": point_step,
        }
    )
    width = int(msg.width)
    rows = _rows(msg.data, int(msg.height), int(msg.row_step), width * point_step, "point cloud")
    points = rows.view(dtype).reshape(-1)
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float32)
    return xyz[np.isfinite(xyz).all(axis=1)]
