"""A saved episode trace placed in the world, as the pictures read it: a thin view over
:class:`~drivenav.eval.trace.EpisodeTrace`.

Poses (``positions``, ``yaws``, ``heights``) are in the world frame, one per step from the start; event points and
bearings are in the episode frame and go to the world through the episode's start pose. A trace without heights (a
one-floor world's) is at height 0 throughout. The view adds only that start pose and the poses as arrays; everything
else is read from the trace it wraps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.trace import Event, EventT, Point, of_type
from drivenav.episode import Episode
from drivenav.eval.trace import EpisodeTrace, StepColumns
from drivenav.types import Pose


@dataclass(frozen=True)
class SavedTrace:
    """``trace`` of an episode that started at ``start`` (world frame); ``positions`` (N x 2), ``yaws`` (N) and
    ``heights`` (N, the agent's feet above the ground floor) are its poses as arrays."""

    trace: EpisodeTrace
    start: Pose
    positions: NDArray[np.float64]
    yaws: NDArray[np.float64]
    heights: NDArray[np.float64]

    @staticmethod
    def of(trace: EpisodeTrace, episode: Episode) -> SavedTrace:
        """The view of ``episode``'s trace; a trace without poses (an episode that failed before its start) cannot
        be drawn: ValueError."""
        positions = np.asarray(trace.positions, dtype=np.float64).reshape(-1, 2)
        yaws = np.asarray(trace.yaws, dtype=np.float64).reshape(-1)
        heights = np.asarray(trace.heights or np.zeros(len(yaws)), dtype=np.float64).reshape(-1)
        if len(positions) == 0 or not len(positions) == len(yaws) == len(heights):
            raise ValueError("positions, yaws (and heights, where given) must be non-empty and of equal length")
        start = Pose(*episode.start_xy, episode.start_yaw, episode.start_height)
        return SavedTrace(trace, start, positions, yaws, heights)

    @property
    def events(self) -> tuple[Event, ...]:
        return self.trace.events

    @property
    def step_ms(self) -> StepColumns:
        """Per module, one latency (ms) per agent step."""
        return self.trace.step_ms

    def of_type(self, kind: type[EventT]) -> list[EventT]:
        """The trace's events of one type, in order."""
        return of_type(self.trace.events, kind)

    def __len__(self) -> int:
        return len(self.positions)

    def index(self, step: int) -> int:
        """The pose index of ``step``, clamped to the trajectory."""
        return min(max(step, 0), len(self) - 1)

    def pose(self, step: int) -> Pose:
        """The world pose at ``step`` (clamped to the trajectory), its height included."""
        index = self.index(step)
        x, y = self.positions[index]
        return Pose(float(x), float(y), float(self.yaws[index]), float(self.heights[index]))

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

    def segments(self) -> list[tuple[int, int]]:
        """``(first, last)`` pose index of each segment; consecutive segments share their boundary pose."""
        last = len(self) - 1
        starts = sorted({min(max(s, 0), last) for s in self.trace.segment_starts} | {0})
        ends = [*starts[1:], last]
        return [(a, b) for a, b in zip(starts, ends, strict=True) if b > a] or [(0, last)]

    def move_segments(self) -> NDArray[np.int64]:
        """Per move ``t`` (pose ``t`` to ``t + 1``): the index into :meth:`segments` it belongs to."""
        firsts = np.array([first for first, _ in self.segments()])
        index: NDArray[np.int64] = np.searchsorted(firsts, np.arange(len(self) - 1), side="right") - 1
        return np.maximum(index, 0)
