"""The ROS 2 side (the drivenav.robot.ros package, paper Sec. V-E): conversions, synchronisation, a real ROS 2 bag
written with rosbags and replayed through BagSource into the field-of-view LiDAR occupancy, and the cmd_vel
closed loop."""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from drivenav.robot.lidar import LidarOccupancy
from drivenav.robot.parts import MotionResult
from drivenav.robot.ros import BagSource, LidarMount, RosMotionExecutor, RosSensorSource, RosTopics
from drivenav.robot.ros.convert import (
    camera_info_to_intrinsics,
    image_to_array,
    image_to_depth,
    image_to_rgb,
    odometry_to_pose,
    pointcloud2_to_xyz,
    stamp_seconds,
)
from drivenav.robot.ros.motion import CmdVelConfig, CmdVelController, Outcome, VelocityCommand
from drivenav.robot.ros.sync import Pairing, Stream, SyncBuffer, SyncConfig, pair_by_time
from drivenav.types import FREE_CELL, OCCUPIED_CELL, UNKNOWN_CELL, Action, CameraIntrinsics, LocalOccupancy, Pose

STORE = get_typestore(Stores.ROS2_HUMBLE)
T = STORE.types
T0 = 1_700_000_000  # seconds: the bag's epoch
HEIGHT, WIDTH = 6, 8

# ------------------------ duck-typed messages (as rclpy or rosbags give them)


def image(encoding: str, pixels: NDArray[Any], pad: int = 0, bigendian: bool = False) -> SimpleNamespace:
    """An Image message with ``pad`` bytes of padding after each row."""
    height, width = pixels.shape[:2]
    ordered = pixels.astype(pixels.dtype.newbyteorder(">" if bigendian else "<"))
    rows = ordered.reshape(height, -1).view(np.uint8)
    data = np.concatenate([rows, np.full((height, pad), 0xEE, dtype=np.uint8)], axis=1).reshape(-1)
    return SimpleNamespace(
        height=height, width=width, encoding=encoding, is_bigendian=int(bigendian), step=rows.shape[1] + pad, data=data
    )


def quaternion(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> SimpleNamespace:
    """The quaternion of Rz(yaw) Ry(pitch) Rx(roll), the product of the three half-angle quaternions."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return SimpleNamespace(
        w=cr * cp * cy + sr * sp * sy,
        x=sr * cp * cy - cr * sp * sy,
        y=cr * sp * cy + sr * cp * sy,
        z=cr * cp * sy - sr * sp * cy,
    )


def cloud_fields(offsets: dict[str, int], datatype: int = 7) -> list[SimpleNamespace]:
    return [SimpleNamespace(name=n, offset=o, datatype=datatype, count=1) for n, o in offsets.items()]


# ------------------------ conversions


def test_rgb8_honours_the_row_padding() -> None:
    pixels = np.arange(HEIGHT * WIDTH * 3, dtype=np.uint8).reshape(HEIGHT, WIDTH, 3)
    rgb = image_to_rgb(image("rgb8", pixels, pad=4))
    assert rgb.dtype == np.uint8 and np.array_equal(rgb, pixels)
    assert np.array_equal(image_to_array(image("rgb8", pixels, pad=4)), pixels)


def test_bgr8_becomes_rgb() -> None:
    bgr = np.zeros((2, 3, 3), dtype=np.uint8)
    bgr[..., 0] = 10  # blue
    bgr[..., 2] = 250  # red
    rgb = image_to_rgb(image("bgr8", bgr))
    assert rgb[0, 0].tolist() == [250, 0, 10]


def test_16uc1_millimetres_to_metres_with_zero_as_no_return() -> None:
    mm = np.array([[0, 1000, 1500], [65535, 250, 1]], dtype=np.uint16)
    for bigendian in (False, True):
        depth = image_to_depth(image("16UC1", mm, pad=2, bigendian=bigendian))
        assert depth.dtype == np.float32
        assert np.isnan(depth[0, 0])
        np.testing.assert_allclose(depth[0, 1:], [1.0, 1.5])
        np.testing.assert_allclose(depth[1], [65.535, 0.25, 0.001], rtol=1e-6)


def test_32fc1_metres_with_non_finite_and_non_positive_as_no_return() -> None:
    metres = np.array([[1.25, np.nan, np.inf], [0.0, -1.0, 3.5]], dtype=np.float32)
    depth = image_to_array(image("32FC1", metres, bigendian=True))
    assert np.isnan(depth).tolist() == [[False, True, True], [True, True, False]]
    assert (depth[0, 0], depth[1, 2]) == (1.25, 3.5)


@pytest.mark.parametrize(
    ("convert", "encoding"),
    [(image_to_rgb, "16UC1"), (image_to_depth, "rgb8"), (image_to_array, "yuv422"), (image_to_depth, "mono16")],
)
def test_wrong_or_unsupported_encodings_are_refused(convert: Callable[[Any], Any], encoding: str) -> None:
    msg = image("rgb8", np.zeros((2, 2, 3), dtype=np.uint8))
    msg.encoding = encoding
    with pytest.raises(ValueError, match="encoding"):
        convert(msg)


def test_short_image_data_is_refused() -> None:
    msg = image("rgb8", np.zeros((2, 2, 3), dtype=np.uint8))
    msg.data = msg.data[:-1]
    with pytest.raises(ValueError, match="too short"):
        image_to_rgb(msg)


def test_camera_info_gives_the_pinhole_intrinsics() -> None:
    msg = SimpleNamespace(width=640, height=480, k=[600.0, 0.0, 320.5, 0.0, 610.0, 240.5, 0.0, 0.0, 1.0])
    assert camera_info_to_intrinsics(msg) == CameraIntrinsics(640, 480, 600.0, 610.0, 320.5, 240.5)
    msg.k = [0.0] * 9
    with pytest.raises(ValueError, match="calibrated"):
        camera_info_to_intrinsics(msg)


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -2.5, math.radians(179.0)])
def test_odometry_gives_the_planar_yaw_even_when_tilted(yaw: float) -> None:
    # Rz(yaw) Ry(11 deg) Rx(10 deg): the robot leans (a walking humanoid), its heading is still yaw (which
    # 2 atan2(z, w) would not give).
    tilted = quaternion(yaw, 0.2, 0.17)
    assert 2 * math.atan2(tilted.z, tilted.w) != pytest.approx(yaw)
    pose = SimpleNamespace(position=SimpleNamespace(x=1.5, y=-2.0, z=0.3), orientation=tilted)
    result = odometry_to_pose(SimpleNamespace(pose=SimpleNamespace(pose=pose)))
    assert (result.x, result.y) == (1.5, -2.0)
    assert result.yaw == pytest.approx(yaw)


def test_stamp_seconds() -> None:
    header = SimpleNamespace(stamp=SimpleNamespace(sec=12, nanosec=500_000_000))
    assert stamp_seconds(header) == 12.5


def test_pointcloud2_reads_xyz_by_offset_with_padding_and_byte_order() -> None:
    # Fields out of order (z first) behind an intensity, 20-byte points, 4 bytes of row padding, big-endian.
    xyz = np.array([[1.0, 2.0, 3.0], [np.nan, 0.0, 0.0], [-4.0, 5.5, 0.25]], dtype=np.float32)
    record = np.zeros((1, 3, 5), dtype=">f4")
    record[0, :, 0] = 7.0  # intensity
    record[0, :, 1], record[0, :, 2], record[0, :, 3] = xyz[:, 2], xyz[:, 0], xyz[:, 1]
    data = np.concatenate([record.view(np.uint8).reshape(1, -1), np.zeros((1, 4), dtype=np.uint8)], axis=1)
    msg = SimpleNamespace(
        height=1,
        width=3,
        fields=cloud_fields({"intensity": 0, "z": 4, "x": 8, "y": 12}),
        is_bigendian=True,
        point_step=20,
        row_step=64,
        data=data.reshape(-1),
    )
    points = pointcloud2_to_xyz(msg)
    assert points.dtype == np.float32
    assert points.tolist() == [[1.0, 2.0, 3.0], [-4.0, 5.5, 0.25]]  # the NaN point dropped


@pytest.mark.parametrize("fields", [cloud_fields({"x": 0, "y": 4}), cloud_fields({"x": 0, "y": 4, "z": 8}, datatype=8)])
def test_pointcloud2_needs_float32_xyz(fields: list[SimpleNamespace]) -> None:
    msg = SimpleNamespace(
        height=1, width=0, fields=fields, is_bigendian=False, point_step=16, row_step=0, data=np.zeros(0, np.uint8)
    )
    with pytest.raises(ValueError, match="FLOAT32"):
        pointcloud2_to_xyz(msg)


def test_lidar_mount_maps_to_the_base_frame_with_z_from_the_floor() -> None:
    # Yawed 90 deg left, 0.1 m ahead, 0.5 m up: (1, 0, -0.2) -> (0.1 + 0, 0 + 1, 0.5 - 0.2).
    turned = LidarMount(x=0.1, z=0.5, yaw=math.pi / 2).to_base([[1.0, 0.0, -0.2]])
    np.testing.assert_allclose(turned, [[0.1, 1.0, 0.3]], atol=1e-6)
    # Upside down (roll pi) 1.2 m up: (x, y, z) -> (x, -y, 1.2 - z).
    inverted = LidarMount(z=1.2, roll=math.pi).to_base([[1.0, 0.5, 0.3]])
    np.testing.assert_allclose(inverted, [[1.0, -0.5, 0.9]], atol=1e-6)
    # Pitched 90 deg down (pitch pi / 2 about y): the sensor's x looks at the floor: (1, 0, 0) -> (0, 0, z - 1).
    pitched = LidarMount(z=1.2, pitch=math.pi / 2).to_base([[1.0, 0.0, 0.0]])
    np.testing.assert_allclose(pitched, [[0.0, 0.0, 0.2]], atol=1e-6)


# ------------------------ synchronisation


def test_pairs_within_50_ms_are_kept_and_farther_ones_rejected() -> None:
    rgb = [10.0, 10.2, 10.4, 10.6]
    depth = [10.05, 10.26, 10.43, 10.6]  # gaps 50 ms (kept), 60 ms (rejected), 30 ms, 0
    odometry = [10.0, 10.1, 10.2, 10.3, 10.4]  # nearest to 10.6: 10.4, 200 ms away (rejected)
    scan = [10.02, 10.33]  # 20 ms from 10.0; 70 ms from 10.4; 130 ms from 10.2
    assert pair_by_time(rgb, depth, odometry, scan) == [Pairing(0, 0, 0, 0), Pairing(2, 2, 4, 1)]
    assert pair_by_time(rgb, depth, odometry, scan, SyncConfig(scan_tolerance=0.05)) == [
        Pairing(0, 0, 0, 0),
        Pairing(2, 2, 4, None),
    ]
    assert pair_by_time(rgb, depth, odometry, scan, SyncConfig(max_skew=0.2))[1] == Pairing(1, 1, 2, None)


def test_pairing_takes_the_nearest_and_the_earlier_on_a_tie() -> None:
    # Stamps 1/32 s either side of the RGB (exact binary fractions): the earlier one.
    tie = [1.0 - 1 / 32, 1.0 + 1 / 32]
    assert pair_by_time([1.0], [*tie, 1.0625], [0.5, 1.0], tie) == [Pairing(0, 0, 1, 0)]


def test_pairing_needs_every_stream_and_ascending_stamps() -> None:
    assert pair_by_time([1.0, 2.0], [], [1.0, 2.0]) == []
    with pytest.raises(ValueError, match="depth stamps"):
        pair_by_time([1.0], [1.0, 0.5], [1.0])


def test_sync_buffer_gives_the_newest_set_after_a_time() -> None:
    buffer = SyncBuffer(horizon=1.0)
    for t in (10.0, 10.2, 10.1):  # out of order arrivals
        buffer.add(Stream.RGB, t, f"rgb{t}")
        buffer.add(Stream.DEPTH, t + 0.01, f"depth{t}")
    buffer.add(Stream.ODOMETRY, 10.05, "odom10.05")
    buffer.add(Stream.ODOMETRY, 10.19, "odom10.19")
    newest = buffer.latest(after=10.0)
    assert newest is not None
    assert (newest.rgb, newest.depth, newest.odometry, newest.scan) == ("rgb10.2", "depth10.2", "odom10.19", None)
    assert buffer.latest(after=10.25) is None
    buffer.add(Stream.ODOMETRY, 11.3, "odom11.3")  # 10.05 and 10.19 fall out of the 1 s horizon
    assert buffer.latest(after=0.0) is None


# ------------------------ a real ROS 2 bag through BagSource

MOUNT = LidarMount(x=0.1, z=0.5)  # the LiDAR 0.1 m ahead of the base centre, 0.5 m above the floor
RGB_PIXELS = (np.arange(HEIGHT * WIDTH * 3) % 251).astype(np.uint8).reshape(HEIGHT, WIDTH, 3)


def header(ms: int) -> Any:
    return T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=T0 + ms // 1000, nanosec=(ms % 1000) * 1_000_000), frame_id="f"
    )


def bag_image(ms: int, encoding: str, pixels: NDArray[Any], pad: int) -> Any:
    plain = image(encoding, pixels, pad=pad)
    return T["sensor_msgs/msg/Image"](
        header=header(ms),
        height=plain.height,
        width=plain.width,
        encoding=encoding,
        is_bigendian=0,
        step=plain.step,
        data=plain.data,
    )


def bag_camera_info(ms: int) -> Any:
    return T["sensor_msgs/msg/CameraInfo"](
        header=header(ms),
        height=HEIGHT,
        width=WIDTH,
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=np.array([500.0, 0.0, 3.5, 0.0, 510.0, 2.5, 0.0, 0.0, 1.0]),
        r=np.eye(3).reshape(-1),
        p=np.zeros(12),
        binning_x=0,
        binning_y=0,
        roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def bag_odometry(ms: int, x: float, y: float, yaw: float) -> Any:
    q = quaternion(yaw)
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=q.x, y=q.y, z=q.z, w=q.w),
    )
    zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return T["nav_msgs/msg/Odometry"](
        header=header(ms),
        child_frame_id="body",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
        ),
    )


def bag_cloud(ms: int, base_points: NDArray[np.float64]) -> Any:
    """A livox-like cloud (x, y, z, intensity FLOAT32) in the LiDAR frame of MOUNT, plus one NaN point."""
    lidar = np.vstack([base_points - [MOUNT.x, 0.0, MOUNT.z], [np.nan, np.nan, np.nan]])
    record = np.zeros((len(lidar), 4), dtype="<f4")
    record[:, :3], record[:, 3] = lidar, 12.0
    field = T["sensor_msgs/msg/PointField"]
    return T["sensor_msgs/msg/PointCloud2"](
        header=header(ms),
        height=1,
        width=len(lidar),
        fields=[field(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(("x", "y", "z", "intensity"))],
        is_bigendian=False,
        point_step=16,
        row_step=16 * len(lidar),
        data=record.view(np.uint8).reshape(-1),
        is_dense=False,
    )


def base_scan() -> NDArray[np.float64]:
    """Base-frame returns: a wall 2.025 m ahead for |y| <= 0.5 at 0.3 m, a return at 60 deg (outside the 79 deg
    field of view), and the floor (0.05 m) and a shelf (1.5 m) 1 m ahead (outside the height band)."""
    ys = np.arange(101) * 0.01 - 0.5
    wall = np.stack([np.full_like(ys, 2.025), ys, np.full_like(ys, 0.3)], axis=1)
    others = [[1.0, math.sqrt(3.0), 0.3], [1.025, 0.025, 0.05], [1.025, 0.025, 1.5]]
    return np.vstack([wall, others])


def depth_mm(value: int) -> NDArray[np.uint16]:
    mm = np.full((HEIGHT, WIDTH), value, dtype=np.uint16)
    mm[0, 0] = 0  # no return
    return mm


def write_bag(path: Path, timeline: list[tuple[int, str, Any]]) -> None:
    types = {
        "/camera/color/image_raw": "sensor_msgs/msg/Image",
        "/camera/aligned_depth_to_color/image_raw": "sensor_msgs/msg/Image",
        "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo",
        "/odom": "nav_msgs/msg/Odometry",
        "/livox/lidar": "sensor_msgs/msg/PointCloud2",
    }
    with Writer(path, version=9) as writer:
        connections = {
            topic: writer.add_connection(topic, msgtype, typestore=STORE) for topic, msgtype in types.items()
        }
        for ms, topic, msg in sorted(timeline, key=lambda item: item[0]):
            data = STORE.serialize_cdr(msg, types[topic])
            writer.write(connections[topic], (T0 * 1000 + ms) * 1_000_000 + 3_000_000, data)  # received 3 ms later


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    """RGB at 0, 200, 400 ms; depth at 0, 260 (60 ms from its RGB: rejected), 430; odometry every 100 ms moving
    0.1 m along x per message at (1 + k / 10, 2) facing +y; scans at 0 and 250 ms (150 ms from the last RGB)."""
    rgb, depth = "/camera/color/image_raw", "/camera/aligned_depth_to_color/image_raw"
    timeline: list[tuple[int, str, Any]] = [(0, "/camera/color/camera_info", bag_camera_info(0))]
    timeline += [(ms, rgb, bag_image(ms, "rgb8", RGB_PIXELS, pad=4)) for ms in (0, 200, 400)]
    timeline += [
        (ms, depth, bag_image(ms, "16UC1", depth_mm(mm), pad=2)) for ms, mm in [(0, 1000), (260, 2000), (430, 3000)]
    ]
    timeline += [(100 * k, "/odom", bag_odometry(100 * k, 1.0 + 0.1 * k, 2.0, math.pi / 2)) for k in range(6)]
    timeline += [(ms, "/livox/lidar", bag_cloud(ms, base_scan())) for ms in (0, 250)]
    path = tmp_path / "run"
    write_bag(path, timeline)
    return path


def cell(window: LocalOccupancy, x: float, y: float) -> int:
    col = math.floor((x - window.origin[0]) / window.resolution)
    row = math.floor((y - window.origin[1]) / window.resolution)
    return int(window.cells[row, col])


def test_bag_frames_are_synchronised_converted_and_in_time_order(bag: Path) -> None:
    source = BagSource(bag, mount=MOUNT, gimbal_yaw=0.1)
    first, second = source.read(), source.read()
    with pytest.raises(EOFError):
        source.read()  # the RGB at 200 ms had no depth within 50 ms
    source.close()
    source.close()

    assert (first.stamp, second.stamp) == (pytest.approx(T0, abs=1e-6), pytest.approx(T0 + 0.4, abs=1e-6))
    assert first.intrinsics == CameraIntrinsics(WIDTH, HEIGHT, 500.0, 510.0, 3.5, 2.5)
    assert np.array_equal(first.rgb, RGB_PIXELS) and np.array_equal(second.rgb, RGB_PIXELS)
    assert np.isnan(first.depth[0, 0]) and np.isnan(second.depth[0, 0])
    assert np.nanmin(first.depth) == np.nanmax(first.depth) == 1.0
    assert np.nanmin(second.depth) == np.nanmax(second.depth) == 3.0  # depth at 430 ms, not 260 ms
    assert first.pose.x == 1.0 and second.pose.x == pytest.approx(1.4)  # odometry at 0 and 400 ms
    assert first.pose.y == second.pose.y == 2.0
    assert first.pose.yaw == pytest.approx(math.pi / 2) and second.pose.yaw == pytest.approx(math.pi / 2)
    assert first.gimbal_yaw == 0.1
    assert first.scan is not None and second.scan is None  # the last scan is 150 ms from the RGB at 400 ms
    np.testing.assert_allclose(first.scan, base_scan(), atol=1e-6)  # mounted, NaN dropped


def test_bag_scan_gives_the_field_of_view_occupancy(bag: Path) -> None:
    source = BagSource(bag, mount=MOUNT)
    frame = source.read()
    source.close()
    assert frame.scan is not None
    grid = LidarOccupancy()
    grid.update(frame.scan, frame.pose, frame.gimbal_yaw)
    window = grid.window(frame.pose)
    # Robot at (1, 2) facing +y: base (f, l) is at (1 - l, 2 + f). The wall (f = 2.025, |l| <= 0.5) lies at
    # y = 4.025 for x in [0.5, 1.5]; between it and the robot is free.
    for x in (0.575, 0.975, 1.025, 1.425):
        assert cell(window, x, 4.025) == OCCUPIED_CELL, x
    for x, y in [(0.975, 2.525), (1.025, 3.525), (0.975, 3.975)]:
        assert cell(window, x, y) == FREE_CELL, (x, y)
    # The return at 60 deg, (1 - sqrt 3, 3), is outside the field of view: never observed.
    assert cell(window, 1.0 - math.sqrt(3.0), 3.0) == UNKNOWN_CELL
    # The floor and shelf returns 1 m ahead, at (0.975, 3.025), are outside the height band: crossed as free.
    assert cell(window, 0.975, 3.025) == FREE_CELL


def test_bag_without_a_scan_topic_and_with_a_missing_topic(bag: Path) -> None:
    source = BagSource(bag, RosTopics(scan=None))
    assert source.read().scan is None
    source.close()
    with pytest.raises(EOFError):
        source.read()  # closed before the second frame
    with pytest.raises(ValueError, match="/Odometry"):
        BagSource(bag, RosTopics(odometry="/Odometry"))


def test_topics_must_be_distinct() -> None:
    with pytest.raises(ValueError, match="distinct"):
        RosTopics(depth="/camera/color/image_raw")


# ------------------------ the cmd_vel closed loop on simulated odometry

DT = 0.05  # s: 20 Hz ticks


def drive(
    controller: CmdVelController, start: Pose, move: Callable[[Pose, VelocityCommand], Pose]
) -> tuple[Outcome, Pose, float]:
    """Tick the controller every DT seconds, the robot following ``move``, until an outcome (at most 60 s)."""
    pose = start
    for tick in range(1200):
        command = controller.step(pose, tick * DT)
        if isinstance(command, Outcome):
            return command, pose, tick * DT
        pose = move(pose, command)
    raise AssertionError("no outcome within 60 s")


def unicycle(pose: Pose, command: VelocityCommand) -> Pose:
    return pose.compose(Pose(command.linear * DT, 0.0, command.angular * DT))


def test_forward_reaches_the_step() -> None:
    # Done once within 1 cm of 0.25 m; the command near the end is at most max(0.05, 2 x 0.02) m/s, 2.5 mm a tick,
    # so the robot stops in [0.24, 0.25] m along its start heading.
    start = Pose(1.0, 2.0, 2.0)
    outcome, pose, _ = drive(CmdVelController(Action.MOVE_FORWARD, start), start, unicycle)
    progress = (pose.x - start.x) * math.cos(start.yaw) + (pose.y - start.y) * math.sin(start.yaw)
    assert outcome is Outcome.DONE
    assert 0.24 <= progress <= 0.25
    assert pose.yaw == pytest.approx(start.yaw)


@pytest.mark.parametrize(("action", "sign"), [(Action.TURN_LEFT, 1.0), (Action.TURN_RIGHT, -1.0)])
def test_turns_stop_within_two_degrees(action: Action, sign: float) -> None:
    start = Pose(0.0, 0.0, 3.0)  # the left turn crosses +-pi
    outcome, pose, elapsed = drive(CmdVelController(action, start), start, unicycle)
    error = math.remainder(pose.yaw - (3.0 + sign * math.radians(30.0)), 2 * math.pi)
    assert outcome is Outcome.DONE
    assert abs(error) <= math.radians(2.0)
    assert (pose.x, pose.y) == (0.0, 0.0)
    assert elapsed < 2.0  # 0.52 rad at up to 0.6 rad/s


def test_a_blocked_forward_step_reports_a_collision() -> None:
    # The robot does not move: no 2 cm of progress within 1 s.
    start = Pose(0.0, 0.0, 0.0)
    outcome, _, elapsed = drive(CmdVelController(Action.MOVE_FORWARD, start), start, lambda pose, _: pose)
    assert outcome is Outcome.BLOCKED
    assert elapsed == pytest.approx(1.0)
    assert outcome.result() == MotionResult(collided=True, completed=False)


def test_a_forward_step_stopped_midway_is_blocked_a_stall_time_after_its_last_progress() -> None:
    # 3 cm a tick up to 6 cm: progress marks at 0.03 m (0.05 s) and 0.06 m (0.1 s), blocked at 0.1 + 1.0 s.
    def stuck_at_6_cm(pose: Pose, _: VelocityCommand) -> Pose:
        return Pose(min(pose.x + 0.03, 0.06), 0.0, 0.0)

    start = Pose(0.0, 0.0, 0.0)
    outcome, pose, elapsed = drive(CmdVelController(Action.MOVE_FORWARD, start), start, stuck_at_6_cm)
    assert outcome is Outcome.BLOCKED
    assert elapsed == pytest.approx(1.1) and pose.x == 0.06


def test_slow_progress_times_out_instead_of_blocking() -> None:
    # 3 cm/s is progress (>= 2 cm per second) but reaches only 9 cm in the 3 s allowed.
    def crawl(pose: Pose, command: VelocityCommand) -> Pose:
        return pose.compose(Pose(min(command.linear, 0.03) * DT, 0.0, 0.0))

    start = Pose(0.0, 0.0, 0.0)
    config = CmdVelConfig(timeout=3.0)
    outcome, pose, elapsed = drive(CmdVelController(Action.MOVE_FORWARD, start, config), start, crawl)
    assert outcome is Outcome.TIMEOUT
    assert elapsed == pytest.approx(3.0) and pose.x == pytest.approx(0.09)
    assert outcome.result() == MotionResult(collided=False, completed=False)


def test_a_turn_that_does_not_happen_times_out() -> None:
    start = Pose(0.0, 0.0, 0.0)
    outcome, _, elapsed = drive(CmdVelController(Action.TURN_LEFT, start), start, lambda pose, _: pose)
    assert outcome is Outcome.TIMEOUT and elapsed == pytest.approx(10.0)
    assert Outcome.DONE.result() == MotionResult(collided=False, completed=True)


def test_commands_are_proportional_and_saturated() -> None:
    start = Pose(0.0, 0.0, 0.0)
    forward = CmdVelController(Action.MOVE_FORWARD, start)
    assert forward.step(start, 0.0) == VelocityCommand(0.2, 0.0)  # 2 x 0.25 saturates at 0.2 m/s
    assert forward.step(Pose(0.2, 0.0, 0.1), 0.5) == VelocityCommand(pytest.approx(0.1), pytest.approx(-0.2))
    right = CmdVelController(Action.TURN_RIGHT, start)
    assert right.step(start, 0.0) == VelocityCommand(0.0, pytest.approx(-0.6))  # 2 x 0.52 saturates
    assert right.step(Pose(0.0, 0.0, math.radians(-25.0)), 0.5) == VelocityCommand(
        0.0, pytest.approx(-2.0 * math.radians(5.0))
    )
    with pytest.raises(ValueError, match="STOP"):
        CmdVelController(Action.STOP, start)


def test_cmd_vel_config_is_validated() -> None:
    with pytest.raises(ValueError, match="timeout"):
        CmdVelConfig(timeout=0.0)
    with pytest.raises(ValueError, match="min_linear_speed"):
        CmdVelConfig(min_linear_speed=0.5)


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="rclpy is installed here")
@pytest.mark.parametrize("make", [RosSensorSource, RosMotionExecutor])
def test_live_parts_need_a_sourced_ros_2(make: Callable[[], object]) -> None:
    with pytest.raises(RuntimeError, match="source your ROS 2 setup"):
        make()
