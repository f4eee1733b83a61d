"""The ROS 2 side of the real robot (paper Sec. V-E): message conversions, time synchronisation, a bag source and
the ``cmd_vel`` motion logic.

The paper's robot, a Unitree G1, carries an RGB-D camera and a LiDAR whose returns are fused with the IMU by
FAST-LIO2. This module turns its ROS 2 messages into frames (:class:`drivenav.robot.parts.SensorFrame`) and one
discrete action into velocity commands closed on odometry. Nothing here imports ``rclpy`` at module level: the
conversions work on duck-typed messages (as deserialised by ``rosbags`` or received by ``rclpy``),
:class:`BagSource` reads a ROS 2 bag with ``rosbags`` (no ROS install needed, imported when a bag is opened), and
only :class:`RosSensorSource` and :class:`RosMotionExecutor` need a sourced ROS 2 environment.

Topics (:class:`RosTopics`) default to a RealSense driver (``realsense2_camera`` with ``align_depth``; version 4
adds a ``/camera/camera`` namespace, pass its names), odometry on ``/odom`` and raw LiDAR returns on
``/livox/lidar`` (``livox_ros_driver2`` with ``xfer_format`` 0 publishes ``sensor_msgs/PointCloud2`` in the LiDAR's
own frame, which :class:`LidarMount` maps to the base frame). FAST-LIO2 publishes its LiDAR-inertial odometry on
``/Odometry`` (frame ``camera_init``): pass ``odometry="/Odometry"`` or remap it; its pose is the IMU's, taken as
the base's. Its ``/cloud_registered`` is not used as the scan: it lies in FAST-LIO2's world frame, not the base.
"""

from __future__ import annotations

import bisect
import importlib
import math
import time
from collections import Counter, deque
from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import dataclass, fields
from enum import Enum
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivenav.grid import wrap_angle
from drivenav.robot.parts import MotionResult, SensorFrame
from drivenav.types import Action, CameraIntrinsics, Pose

RosMessage = Any
"""A ROS 2 message object, read by attribute (``rosbags``' dataclasses and ``rclpy``'s classes alike)."""

_FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
_STAMP_SLACK = 1e-6  # seconds: float rounding of epoch stamps when comparing with a tolerance
_COLOUR_ENCODINGS = ("rgb8", "bgr8")
_DEPTH_ENCODINGS = ("16UC1", "32FC1")
_IMAGE_LAYOUTS = {"rgb8": ("u1", 3), "bgr8": ("u1", 3), "16UC1": ("u2", 1), "32FC1": ("f4", 1)}


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


# ------------------------------------------------------------------------------------------------ conversions


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
    """A ``nav_msgs/Odometry``'s planar pose: position x, y and the yaw of its orientation quaternion."""
    position, q = msg.pose.pose.position, msg.pose.pose.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return Pose(float(position.x), float(position.y), yaw)


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


# ------------------------------------------------------------------------------------------------ synchronisation


class Stream(Enum):
    """The time-synchronised streams of a frame."""

    RGB = "rgb"
    DEPTH = "depth"
    ODOMETRY = "odometry"
    SCAN = "scan"


@dataclass(frozen=True)
class SyncConfig:
    """Synchronisation tolerances in seconds: depth and odometry within ``max_skew`` of the RGB image (pairs
    farther apart are rejected), the scan within ``scan_tolerance`` (else the frame has no scan)."""

    max_skew: float = 0.050
    scan_tolerance: float = 0.1

    def __post_init__(self) -> None:
        if not self.max_skew >= 0.0:
            raise ValueError(f"SyncConfig.max_skew must be >= 0, got {self.max_skew}")
        if not self.scan_tolerance >= 0.0:
            raise ValueError(f"SyncConfig.scan_tolerance must be >= 0, got {self.scan_tolerance}")


@dataclass(frozen=True)
class Pairing:
    """Indices of the messages that make one frame (``scan`` None: no scan near enough)."""

    rgb: int
    depth: int
    odometry: int
    scan: int | None

    def messages(self) -> list[tuple[Stream, int]]:
        """Each message as its stream and index."""
        keys = [(Stream.RGB, self.rgb), (Stream.DEPTH, self.depth), (Stream.ODOMETRY, self.odometry)]
        return keys if self.scan is None else [*keys, (Stream.SCAN, self.scan)]


def pair_by_time(
    rgb: Sequence[float],
    depth: Sequence[float],
    odometry: Sequence[float],
    scan: Sequence[float] = (),
    config: SyncConfig | None = None,
) -> list[Pairing]:
    """Pair each RGB stamp with the nearest depth and odometry stamps and the nearest scan stamp.

    Each sequence holds one stream's stamps in seconds, ascending. An RGB image whose nearest depth image or
    odometry message is more than ``max_skew`` away makes no frame; a scan more than ``scan_tolerance`` away is
    left out (``scan`` None). Returns the pairings in RGB order, as indices into the sequences.
    """
    sync = config or SyncConfig()
    targets = _ascending("rgb", rgb)
    depth_index, depth_gap = _nearest(_ascending("depth", depth), targets)
    odometry_index, odometry_gap = _nearest(_ascending("odometry", odometry), targets)
    scan_index, scan_gap = _nearest(_ascending("scan", scan), targets)
    kept = (depth_gap <= sync.max_skew + _STAMP_SLACK) & (odometry_gap <= sync.max_skew + _STAMP_SLACK)
    with_scan = scan_gap <= sync.scan_tolerance + _STAMP_SLACK
    return [
        Pairing(i, int(depth_index[i]), int(odometry_index[i]), int(scan_index[i]) if with_scan[i] else None)
        for i in np.flatnonzero(kept).tolist()
    ]


def _ascending(name: str, stamps: Sequence[float]) -> NDArray[np.float64]:
    array = np.asarray(stamps, dtype=np.float64).reshape(-1)
    if np.any(np.diff(array) < 0.0):
        raise ValueError(f"{name} stamps must be in ascending order")
    return array


def _nearest(
    stamps: NDArray[np.float64], targets: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """For each target, the index of the nearest of the sorted ``stamps`` (the earlier on a tie) and the gap;
    gap ``inf`` where there are no stamps."""
    if stamps.size == 0:
        return np.full(targets.shape, -1, dtype=np.int64), np.full(targets.shape, np.inf)
    after = np.clip(np.searchsorted(stamps, targets), 0, stamps.size - 1)
    before = np.clip(after - 1, 0, stamps.size - 1)
    index = np.where(np.abs(targets - stamps[before]) <= np.abs(stamps[after] - targets), before, after)
    return index.astype(np.int64), np.abs(stamps[index] - targets)


@dataclass(frozen=True)
class MessageSet:
    """The messages of one synchronised frame."""

    rgb: RosMessage
    depth: RosMessage
    odometry: RosMessage
    scan: RosMessage | None

    @staticmethod
    def of(pairing: Pairing, message: Callable[[tuple[Stream, int]], RosMessage]) -> MessageSet:
        """The messages a pairing names, each looked up by its stream and index."""
        return MessageSet(
            message((Stream.RGB, pairing.rgb)),
            message((Stream.DEPTH, pairing.depth)),
            message((Stream.ODOMETRY, pairing.odometry)),
            None if pairing.scan is None else message((Stream.SCAN, pairing.scan)),
        )


class SyncBuffer:
    """The recent messages of a live robot, kept for ``horizon`` seconds per stream, and the newest synchronised
    set among them (:func:`pair_by_time`)."""

    def __init__(self, config: SyncConfig | None = None, horizon: float = 1.0) -> None:
        self.config = config or SyncConfig()
        self.horizon = horizon
        self._stamps: dict[Stream, list[float]] = {stream: [] for stream in Stream}
        self._messages: dict[Stream, list[RosMessage]] = {stream: [] for stream in Stream}

    def add(self, stream: Stream, stamp: float, message: RosMessage) -> None:
        """Keep a message (in stamp order, whatever the arrival order) and drop the stream's stale ones."""
        stamps, messages = self._stamps[stream], self._messages[stream]
        at = bisect.bisect_right(stamps, stamp)
        stamps.insert(at, stamp)
        messages.insert(at, message)
        stale = bisect.bisect_left(stamps, stamps[-1] - self.horizon)
        del stamps[:stale], messages[:stale]

    def latest(self, after: float) -> MessageSet | None:
        """The newest synchronised set whose RGB stamp is at or after ``after``, or None."""
        s = self._stamps
        pairings = pair_by_time(s[Stream.RGB], s[Stream.DEPTH], s[Stream.ODOMETRY], s[Stream.SCAN], self.config)
        if not pairings or s[Stream.RGB][pairings[-1].rgb] < after:
            return None
        return MessageSet.of(pairings[-1], lambda key: self._messages[key[0]][key[1]])


def assemble_frame(
    messages: MessageSet, intrinsics: CameraIntrinsics, mount: LidarMount, gimbal_yaw: float = 0.0
) -> SensorFrame:
    """A :class:`SensorFrame` from synchronised messages, stamped with the RGB image's time; the scan mapped to
    the base frame by ``mount``."""
    rgb, depth = image_to_rgb(messages.rgb), image_to_depth(messages.depth)
    if depth.shape != rgb.shape[:2] or (intrinsics.height, intrinsics.width) != depth.shape:
        raise ValueError(
            f"RGB {rgb.shape[:2]}, depth {depth.shape} and camera_info "
            f"{(intrinsics.height, intrinsics.width)} must have one size (is depth aligned to colour?)"
        )
    scan = None if messages.scan is None else mount.to_base(pointcloud2_to_xyz(messages.scan))
    return SensorFrame(
        rgb=rgb,
        depth=depth,
        pose=odometry_to_pose(messages.odometry),
        intrinsics=intrinsics,
        stamp=stamp_seconds(messages.rgb.header),
        gimbal_yaw=gimbal_yaw,
        scan=scan,
    )


# ------------------------------------------------------------------------------------------------ bag source


class BagSource:
    """Synchronised frames from a ROS 2 bag, read with ``rosbags`` (no ROS install needed), in RGB time order.

    The bag is read twice: once for the header stamps (and the first camera_info), which :func:`pair_by_time`
    pairs, and once for the frames, holding only the messages a pending frame still needs. :meth:`read` raises
    ``EOFError`` when the bag is exhausted (a live source raises ``TimeoutError`` instead).
    """

    def __init__(
        self,
        path: str | Path,
        topics: RosTopics | None = None,
        *,
        mount: LidarMount | None = None,
        gimbal_yaw: float = 0.0,
        sync: SyncConfig | None = None,
    ) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.topics = topics or RosTopics()
        self.mount = mount or LidarMount()
        self.gimbal_yaw = gimbal_yaw
        self._reader = AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        self._reader.open()
        try:
            self._streams = self._stream_topics()
            self._connections = [c for c in self._reader.connections if c.topic in self._streams]
            self._connections += [c for c in self._reader.connections if c.topic == self.topics.camera_info]
            self._intrinsics, plan = self._plan(sync or SyncConfig())
        except BaseException:
            self._reader.close()
            raise
        self._frames = self._generate(plan)
        self._closed = False

    def read(self) -> SensorFrame:
        """The next synchronised frame; ``EOFError`` once the bag holds no more."""
        frame = next(self._frames, None)
        if frame is None:
            raise EOFError("the bag holds no more synchronised frames")
        return frame

    def close(self) -> None:
        """Close the bag; :meth:`read` then raises ``EOFError`` (closing again: no effect)."""
        if not self._closed:
            self._closed = True
            self._frames.close()
            self._reader.close()

    def _stream_topics(self) -> dict[str, Stream]:
        topics = {self.topics.rgb: Stream.RGB, self.topics.depth: Stream.DEPTH, self.topics.odometry: Stream.ODOMETRY}
        if self.topics.scan:
            topics[self.topics.scan] = Stream.SCAN
        missing = sorted((set(topics) | {self.topics.camera_info}) - set(self._reader.topics))
        if missing:
            raise ValueError(f"the bag has no topic {', '.join(missing)} (it has {sorted(self._reader.topics)})")
        return topics

    def _messages(self) -> Iterator[tuple[str, str, bytes]]:
        """The topic, type and raw data of every message of the frame topics and camera_info, in bag order."""
        for connection, _, raw in self._reader.messages(connections=self._connections):
            yield connection.topic, connection.msgtype, raw

    def _plan(self, sync: SyncConfig) -> tuple[CameraIntrinsics, list[Pairing]]:
        """First pass: the camera intrinsics and the frames' pairings, as bag-order positions in each stream, in
        RGB time order."""
        stamps: dict[Stream, list[float]] = {stream: [] for stream in Stream}
        intrinsics: CameraIntrinsics | None = None
        for topic, msgtype, raw in self._messages():
            msg: RosMessage = self._reader.deserialize(raw, msgtype)
            if topic == self.topics.camera_info:
                intrinsics = intrinsics or camera_info_to_intrinsics(msg)
            else:
                stamps[self._streams[topic]].append(stamp_seconds(msg.header))
        if intrinsics is None:
            raise ValueError(f"the bag has no message on {self.topics.camera_info}")
        order = {stream: np.argsort(np.asarray(stamps[stream]), kind="stable").tolist() for stream in Stream}
        ordered = {stream: [stamps[stream][i] for i in order[stream]] for stream in Stream}
        pairings = pair_by_time(
            ordered[Stream.RGB], ordered[Stream.DEPTH], ordered[Stream.ODOMETRY], ordered[Stream.SCAN], sync
        )
        return intrinsics, [
            Pairing(
                order[Stream.RGB][p.rgb],
                order[Stream.DEPTH][p.depth],
                order[Stream.ODOMETRY][p.odometry],
                None if p.scan is None else order[Stream.SCAN][p.scan],
            )
            for p in pairings
        ]

    def _generate(self, plan: list[Pairing]) -> Generator[SensorFrame, None, None]:
        """Second pass: each frame as soon as its messages have been read, in RGB time order, deserialising and
        holding only the messages a pending frame needs."""
        pending = deque(plan)
        wanted = Counter(key for pairing in plan for key in pairing.messages())
        held: dict[tuple[Stream, int], RosMessage] = {}
        seen: Counter[Stream] = Counter()
        for topic, msgtype, raw in self._messages():
            if topic == self.topics.camera_info:
                continue
            key = (self._streams[topic], seen[self._streams[topic]])
            seen[key[0]] += 1
            if key in wanted:
                held[key] = self._reader.deserialize(raw, msgtype)
            while pending and all(k in held for k in pending[0].messages()):
                pairing = pending.popleft()
                yield assemble_frame(
                    MessageSet.of(pairing, held.__getitem__), self._intrinsics, self.mount, self.gimbal_yaw
                )
                for k in pairing.messages():
                    wanted[k] -= 1
                    if not wanted[k]:
                        del wanted[k], held[k]


# ------------------------------------------------------------------------------------------------ cmd_vel logic


@dataclass(frozen=True)
class CmdVelConfig:
    """The closed-loop ``cmd_vel`` executor of one discrete action (paper Sec. V-E: the agent's 0.25 m steps and
    30 degree turns on the real robot).

    Speeds in m/s and rad/s: a proportional command ``gain`` x (remaining distance or angle), saturated to
    ``[min_*, *_speed]``; forward motion also holds the start heading. Done within ``forward_tolerance`` metres of
    the step or ``turn_tolerance_deg`` of the turn; ``timeout`` seconds in all; a forward step that gains less
    than ``stall_distance`` in ``stall_time`` seconds is blocked (a collision).
    """

    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    linear_speed: float = 0.2
    min_linear_speed: float = 0.05
    angular_speed: float = 0.6
    min_angular_speed: float = 0.15
    gain: float = 2.0
    forward_tolerance: float = 0.01
    turn_tolerance_deg: float = 2.0
    timeout: float = 10.0
    stall_time: float = 1.0
    stall_distance: float = 0.02

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"CmdVelConfig.{item.name} must be positive and finite, got {value}")
        if self.min_linear_speed > self.linear_speed:
            raise ValueError(f"CmdVelConfig.min_linear_speed must be at most linear_speed, got {self.min_linear_speed}")
        if self.min_angular_speed > self.angular_speed:
            raise ValueError(
                f"CmdVelConfig.min_angular_speed must be at most angular_speed, got {self.min_angular_speed}"
            )


@dataclass(frozen=True)
class VelocityCommand:
    """One ``geometry_msgs/Twist``: forward speed (m/s) and yaw rate (rad/s, counter-clockwise)."""

    linear: float
    angular: float


class Outcome(Enum):
    """How an action ended."""

    DONE = "done"
    TIMEOUT = "timeout"
    BLOCKED = "blocked"

    def result(self) -> MotionResult:
        """Blocked is Habitat's ``collided``; only done counts as completed."""
        return MotionResult(collided=self is Outcome.BLOCKED, completed=self is Outcome.DONE)


class CmdVelController:
    """The pure closed loop of one MOVE_FORWARD, TURN_LEFT or TURN_RIGHT on odometry: each :meth:`step` takes the
    current odometry pose and the time since the start and returns the velocity to command or the outcome."""

    def __init__(self, action: Action, start: Pose, config: CmdVelConfig | None = None) -> None:
        if action == Action.STOP:
            raise ValueError("STOP has no closed loop: stop at once")
        self.config = config or CmdVelConfig()
        self.action = action
        self.start = start
        sign = 1.0 if action == Action.TURN_LEFT else -1.0
        self._target_yaw = start.yaw + sign * math.radians(self.config.turn_angle_deg)
        self._progress_mark = (0.0, 0.0)  # (progress, elapsed) when the forward progress last grew enough

    def step(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        """The command for odometry ``pose`` at ``elapsed`` seconds, or how the action ended."""
        return self._forward(pose, elapsed) if self.action == Action.MOVE_FORWARD else self._turn(pose, elapsed)

    def _forward(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        c = self.config
        dx, dy = pose.x - self.start.x, pose.y - self.start.y
        progress = dx * math.cos(self.start.yaw) + dy * math.sin(self.start.yaw)  # along the start heading
        remaining = c.forward_step - progress
        if remaining <= c.forward_tolerance:
            return Outcome.DONE
        if elapsed >= c.timeout:
            return Outcome.TIMEOUT
        if progress >= self._progress_mark[0] + c.stall_distance:
            self._progress_mark = (progress, elapsed)
        elif elapsed - self._progress_mark[1] >= c.stall_time:
            return Outcome.BLOCKED
        heading_error = wrap_angle(self.start.yaw - pose.yaw)
        return VelocityCommand(
            _clip(c.gain * remaining, c.min_linear_speed, c.linear_speed),
            _clip(c.gain * heading_error, -c.angular_speed, c.angular_speed),
        )

    def _turn(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        c = self.config
        error = wrap_angle(self._target_yaw - pose.yaw)
        if abs(error) <= math.radians(c.turn_tolerance_deg):
            return Outcome.DONE
        if elapsed >= c.timeout:
            return Outcome.TIMEOUT
        return VelocityCommand(
            0.0, math.copysign(_clip(c.gain * abs(error), c.min_angular_speed, c.angular_speed), error)
        )


def _clip(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


# ------------------------------------------------------------------------------------------------ rclpy nodes


def _ros_module(name: str) -> ModuleType:
    """Import a ROS 2 Python module, which only a sourced ROS 2 environment provides."""
    try:
        return importlib.import_module(name)
    except ImportError as err:
        raise RuntimeError("rclpy is not installed: source your ROS 2 setup") from err


def _ros_node(name: str) -> tuple[ModuleType, Any]:
    """``rclpy`` (initialised once per process) and a new node."""
    rclpy = _ros_module("rclpy")
    if not rclpy.ok():
        rclpy.init()
    return rclpy, rclpy.create_node(name)


class RosSensorSource:
    """Synchronised frames from live ROS 2 topics (an ``rclpy`` node, spun by :meth:`read`).

    :meth:`read` returns the newest synchronised frame whose RGB image was stamped at or after the call (so no
    image taken while the robot was still moving), which assumes the camera stamps with the node's clock (the
    RealSense driver's default system time); ``TimeoutError`` if none comes within ``timeout`` seconds.
    """

    def __init__(
        self,
        topics: RosTopics | None = None,
        *,
        mount: LidarMount | None = None,
        gimbal_yaw: float = 0.0,
        sync: SyncConfig | None = None,
        timeout: float = 2.0,
        node_name: str = "drivenav_sensors",
    ) -> None:
        self.topics = topics or RosTopics()
        self.mount = mount or LidarMount()
        self.gimbal_yaw = gimbal_yaw
        self.timeout = timeout
        self._buffer = SyncBuffer(sync)
        self._intrinsics: CameraIntrinsics | None = None
        self._rclpy, self._node = _ros_node(node_name)
        sensor_msgs, nav_msgs = _ros_module("sensor_msgs.msg"), _ros_module("nav_msgs.msg")
        qos = _ros_module("rclpy.qos").qos_profile_sensor_data
        subscriptions = [
            (sensor_msgs.Image, self.topics.rgb, Stream.RGB),
            (sensor_msgs.Image, self.topics.depth, Stream.DEPTH),
            (nav_msgs.Odometry, self.topics.odometry, Stream.ODOMETRY),
        ]
        if self.topics.scan:
            subscriptions.append((sensor_msgs.PointCloud2, self.topics.scan, Stream.SCAN))
        for msg_type, topic, stream in subscriptions:
            self._node.create_subscription(msg_type, topic, self._keeper(stream), qos)
        self._node.create_subscription(sensor_msgs.CameraInfo, self.topics.camera_info, self._on_camera_info, qos)

    def read(self) -> SensorFrame:
        """The newest synchronised frame taken after the call (see the class docstring)."""
        since = self._node.get_clock().now().nanoseconds * 1e-9
        deadline = time.monotonic() + self.timeout
        while True:
            messages = self._buffer.latest(after=since)
            if messages is not None and self._intrinsics is not None:
                return assemble_frame(messages, self._intrinsics, self.mount, self.gimbal_yaw)
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise TimeoutError(f"no synchronised frame on {self.topics} within {self.timeout} s")
            self._rclpy.spin_once(self._node, timeout_sec=min(remaining, 0.05))

    def close(self) -> None:
        """Destroy the node."""
        self._node.destroy_node()

    def _keeper(self, stream: Stream) -> Callable[[RosMessage], None]:
        """The subscription callback that keeps a stream's messages."""

        def keep(msg: RosMessage) -> None:
            self._buffer.add(stream, stamp_seconds(msg.header), msg)

        return keep

    def _on_camera_info(self, msg: RosMessage) -> None:
        self._intrinsics = camera_info_to_intrinsics(msg)


class RosMotionExecutor:
    """Discrete actions as ``geometry_msgs/Twist`` on ``cmd_vel``, closed on odometry by :class:`CmdVelController`
    (an ``rclpy`` node, spun by :meth:`execute`; commands at ``rate_hz``)."""

    def __init__(
        self,
        odometry_topic: str = "/odom",
        cmd_vel_topic: str = "cmd_vel",
        *,
        config: CmdVelConfig | None = None,
        rate_hz: float = 20.0,
        node_name: str = "drivenav_motion",
    ) -> None:
        self.config = config or CmdVelConfig()
        self.period = 1.0 / rate_hz
        self._rclpy, self._node = _ros_node(node_name)
        self._twist = _ros_module("geometry_msgs.msg").Twist
        self._publisher = self._node.create_publisher(self._twist, cmd_vel_topic, 10)
        self._node.create_subscription(_ros_module("nav_msgs.msg").Odometry, odometry_topic, self._on_odometry, 10)
        self._pose: Pose | None = None

    def execute(self, action: Action) -> MotionResult:
        """Carry out ``action`` (STOP: stop at once); ``TimeoutError`` if no odometry comes within the action's
        timeout."""
        if action == Action.STOP:
            self.stop()
            return MotionResult(collided=False)
        start = time.monotonic()
        self._spin_for(self.period)  # the newest odometry, not one queued while idle
        while self._pose is None:
            if time.monotonic() - start >= self.config.timeout:
                raise TimeoutError("no odometry received")
            self._spin_for(self.period)
        controller = CmdVelController(action, self._pose, self.config)
        start = time.monotonic()
        while True:
            command = controller.step(self._pose, time.monotonic() - start)
            if isinstance(command, Outcome):
                self.stop()
                return command.result()
            self._publish(command.linear, command.angular)
            self._spin_for(self.period)

    def stop(self) -> None:
        """Command zero velocity."""
        self._publish(0.0, 0.0)

    def close(self) -> None:
        """Stop and destroy the node."""
        self.stop()
        self._node.destroy_node()

    def _publish(self, linear: float, angular: float) -> None:
        twist = self._twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        self._publisher.publish(twist)

    def _spin_for(self, seconds: float) -> None:
        """Handle odometry callbacks for ``seconds``."""
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0.0:
            self._rclpy.spin_once(self._node, timeout_sec=remaining)

    def _on_odometry(self, msg: RosMessage) -> None:
        self._pose = odometry_to_pose(msg)
