"""A saved episode trace (``RUN_DIR/traces/<id>.json``) as the pictures read it.

Poses (``positions``, ``yaws``) are in the world frame, one per step from the start; event points and bearings
are in the episode frame and go to the world through the episode's start pose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.episode import Episode
from drivenav.types import Pose

Point = tuple[float, float]


@dataclass(frozen=True)
class SavedTrace:
    start: Pose
    positions: NDArray[np.float64]
    yaws: NDArray[np.float64]
    segment_starts: tuple[int, ...]
    events: tuple[dict[str, Any], ...]
    step_ms: dict[str, list[float]] = field(default_factory=dict)  # per module, one latency per step

    @staticmethod
    def from_json(data: dict[str, Any], episode: Episode) -> SavedTrace:
        """Raises KeyError, TypeError or ValueError on a malformed trace."""
        positions = np.asarray(data["positions"], dtype=np.float64).reshape(-1, 2)
        yaws = np.asarray(data["yaws"], dtype=np.float64).reshape(-1)
        if len(positions) == 0 or len(positions) != len(yaws):
            raise ValueError("positions and yaws must be non-empty and of equal length")
        return SavedTrace(
            start=Pose(*episode.start_xy, episode.start_yaw),
            positions=positions,
            yaws=yaws,
            segment_starts=tuple(int(s) for s in data.get("segment_starts", ())),
            events=tuple(dict(e) for e in data.get("events", ())),
            step_ms={str(k): [float(v) for v in values] for k, values in data.get("step_ms", {}).items()},
        )

    def __len__(self) -> int:
        return len(self.positions)

    def pose(self, step: int) -> Pose:
        """The world pose at ``step`` (clamped to the trajectory)."""
        index = min(max(step, 0), len(self) - 1)
        return Pose(float(self.positions[index, 0]), float(self.positions[index, 1]), float(self.yaws[index]))

    def xy(self, step: int) -> Point:
        pose = self.pose(step)
        return pose.x, pose.y

    def to_world(self, point: Sequence[float]) -> Point:
        """An episode-frame point in the world frame."""
        world = self.start.compose(Pose(float(point[0]), float(point[1]), 0.0))
        return world.x, world.y

    def world_yaw(self, yaw: float) -> float:
        """An episode-frame heading or bearing in the world frame."""
        return self.start.yaw + yaw

    def of_kind(self, kind: str) -> list[dict[str, Any]]:
        return [e for e in self.events if e.get("kind") == kind]

    def segments(self) -> list[tuple[int, int]]:
        """``(first, last)`` pose index of each segment; consecutive segments share their boundary pose."""
        last = len(self) - 1
        starts = sorted({min(max(s, 0), last) for s in self.segment_starts} | {0})
        ends = [*starts[1:], last]
        return [(a, b) for a, b in zip(starts, ends, strict=True) if b > a] or [(0, last)]

    def move_segments(self) -> NDArray[np.int64]:
        """Per move ``t`` (pose ``t`` to ``t + 1``): the index into :meth:`segments` it belongs to."""
        firsts = np.array([first for first, _ in self.segments()])
        index: NDArray[np.int64] = np.searchsorted(firsts, np.arange(len(self) - 1), side="right") - 1
        return np.maximum(index, 0)
