"""Synchronised frames replayed from a recorded ROS 2 bag (paper Sec. V-E), read with ``rosbags`` so that no
ROS install is needed: the offline counterpart of :class:`drivenav.robot.ros.nodes.RosSensorSource`."""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Generator, Iterator
from pathlib import Path

import numpy as np

from drivenav.robot.parts import SensorFrame
from drivenav.robot.ros.convert import RosMessage, camera_info_to_intrinsics, stamp_seconds
from drivenav.robot.ros.sync import MessageSet, Pairing, Stream, SyncConfig, assemble_frame, pair_by_time
from drivenav.robot.ros.topics import LidarMount, RosTopics
from drivenav.types import CameraIntrinsics


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
