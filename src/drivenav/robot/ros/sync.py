"""Time synchronisation of the robot's streams (paper Sec. V-E): each RGB image paired with the nearest depth
image, odometry message and LiDAR scan by header stamp, for a recorded bag (:func:`pair_by_time`) and a live robot
(:class:`SyncBuffer`), and one synchronised set assembled into a :class:`SensorFrame`."""

from __future__ import annotations

import bisect
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivenav.robot.parts import SensorFrame
from drivenav.robot.ros.convert import (
    RosMessage,
    image_to_depth,
    image_to_rgb,
    odometry_to_pose,
    pointcloud2_to_xyz,
    stamp_seconds,
)
from drivenav.robot.ros.topics import LidarMount
from drivenav.types import CameraIntrinsics

_STAMP_SLACK = 1e-6  # seconds: float rounding of epoch stamps when comparing with a tolerance


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
