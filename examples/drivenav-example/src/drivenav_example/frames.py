"""A robot's parts for a bring-up without the robot: a sensor source that replays frames saved as ``.npz`` files
(``rgb`` uint8 HxWx3, ``depth`` metres HxW, ``pose`` x, y, yaw) from a folder in name order, and a motion executor
that prints each action and moves nothing. Imported when ``drivenav robot serve`` builds them (:mod:`.robot`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from drivenav.robot.parts import MotionResult, SensorFrame
from drivenav.types import Action, CameraIntrinsics, Pose


class FolderSource:
    """The frames of ``folder`` in name order, seen through ``intrinsics``; ``TimeoutError`` once all were read."""

    def __init__(self, folder: Path, intrinsics: CameraIntrinsics) -> None:
        self.files = sorted(folder.glob("*.npz"))
        self.intrinsics = intrinsics
        self.read_count = 0

    def read(self) -> SensorFrame:
        if self.read_count >= len(self.files):
            raise TimeoutError(f"all {len(self.files)} frames were read")
        with np.load(self.files[self.read_count]) as frame:
            x, y, yaw = (float(v) for v in frame["pose"])
            rgb, depth = frame["rgb"].astype(np.uint8), frame["depth"].astype(np.float32)
        self.read_count += 1
        return SensorFrame(rgb, depth, Pose(x, y, yaw), self.intrinsics, stamp=float(self.read_count))

    def close(self) -> None:
        """Nothing is held open."""


class PrintedMotion:
    """Prints each action (and each stop) on its own line; nothing moves, nothing collides."""

    def execute(self, action: Action) -> MotionResult:
        print(f"action {action.name}", flush=True)
        return MotionResult(collided=False)

    def stop(self) -> None:
        print("stop", flush=True)
