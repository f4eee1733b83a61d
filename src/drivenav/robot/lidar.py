"""LiDAR returns to a 2-D occupancy grid inside the camera's field of view (paper Sec. V-E).

On the real robot (a Unitree G1) LiDAR and IMU are fused by FAST-LIO2, and the 2-D occupancy grid the agent gets
keeps only the LiDAR returns inside the camera's forward 79 degree field of view, so that the map holds no more
than the camera could have seen. Here a scan (base-frame points, ``z`` from the floor, see
:class:`drivenav.robot.parts.SensorFrame`) is cut to the agent's obstacle height band and to the camera's field of
view (gimbal included), reduced to the nearest return per bearing bin (:func:`fov_ranges`), and cast as rays into a
log-odds grid in the episode frame (:class:`LidarOccupancy`); :meth:`LidarOccupancy.window` is the
:class:`drivenav.types.LocalOccupancy` sent to the brain.

Grid convention as in :mod:`drivenav.grid`: cell ``(row, col)`` of the episode-frame lattice covers
``x in [col * res, (col + 1) * res)`` and ``y in [row * res, (row + 1) * res)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivenav.types import FREE_CELL, OCCUPIED_CELL, UNKNOWN_CELL, LocalOccupancy, Pose


@dataclass(frozen=True)
class LidarConfig:
    """Settings of the field-of-view LiDAR occupancy (paper Sec. V-E).

    ``min_height`` .. ``max_height``: the obstacle height band in metres above the floor (the agent's own band);
    ``hfov_deg``: the camera's horizontal field of view, split into ``round(hfov_deg / bin_deg)`` equal bearing
    bins; ``max_range``: returns farther than this are ignored and bins with no return are cast free up to it;
    ``resolution``: cell size; ``window``: side in metres of the window sent around the robot. Log odds:
    ``hit`` for the cell of a return, ``miss`` for the cells a ray crosses before it, clamped to
    ``[clamp_min, clamp_max]``; a cell at or above ``occupied_threshold`` is occupied, at or below
    ``free_threshold`` free, unknown in between (so a cell never observed, at 0, is unknown).
    """

    min_height: float = 0.15
    max_height: float = 0.88
    hfov_deg: float = 79.0
    bin_deg: float = 0.5
    max_range: float = 10.0
    resolution: float = 0.05
    window: float = 10.0
    hit: float = 0.85
    miss: float = -0.4
    clamp_min: float = -2.0
    clamp_max: float = 3.5
    occupied_threshold: float = 0.6
    free_threshold: float = -0.4

    def __post_init__(self) -> None:
        for item in fields(self):
            if not math.isfinite(getattr(self, item.name)):
                raise ValueError(f"LidarConfig.{item.name} must be finite, got {getattr(self, item.name)}")
        _require(self.min_height < self.max_height, "max_height", "greater than min_height", self.max_height)
        _require(0.0 < self.hfov_deg <= 360.0, "hfov_deg", "in (0, 360]", self.hfov_deg)
        _require(0.0 < self.bin_deg <= self.hfov_deg, "bin_deg", "in (0, hfov_deg]", self.bin_deg)
        _require(self.max_range > 0.0, "max_range", "positive", self.max_range)
        _require(self.resolution > 0.0, "resolution", "positive", self.resolution)
        _require(self.window >= self.resolution, "window", "at least one cell", self.window)
        _require(self.hit > 0.0, "hit", "positive", self.hit)
        _require(self.miss < 0.0, "miss", "negative", self.miss)
        _require(self.free_threshold < 0.0, "free_threshold", "negative", self.free_threshold)
        _require(self.occupied_threshold > 0.0, "occupied_threshold", "positive", self.occupied_threshold)
        _require(self.clamp_min <= self.free_threshold, "clamp_min", "at most free_threshold", self.clamp_min)
        _require(self.clamp_max >= self.occupied_threshold, "clamp_max", "at least occupied_threshold", self.clamp_max)

    @property
    def bins(self) -> int:
        """The number of bearing bins across the field of view."""
        return max(1, round(self.hfov_deg / self.bin_deg))


def _require(ok: bool, name: str, expected: str, got: float) -> None:
    if not ok:
        raise ValueError(f"LidarConfig.{name} must be {expected}, got {got}")


def fov_ranges(
    points: ArrayLike, camera_yaw_in_base: float, config: LidarConfig
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The nearest horizontal range per bearing bin of the camera's field of view (paper Sec. V-E).

    ``points`` are (N, 3) base-frame LiDAR returns ``(x forward, y left, z up from the floor)``; the camera looks
    along ``camera_yaw_in_base`` (the gimbal yaw). Kept: returns with ``min_height <= z <= max_height``, a bearing
    within ``hfov_deg / 2`` of the camera axis and a horizontal range in ``(0, max_range]``. Returns the bins'
    centre bearings (radians, relative to the camera axis, increasing to the left) and their nearest ranges, ``inf``
    where a bin has no return.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    horizontal = np.hypot(pts[:, 0], pts[:, 1])
    bearing = _wrap(np.arctan2(pts[:, 1], pts[:, 0]) - camera_yaw_in_base)
    half = math.radians(config.hfov_deg) / 2.0
    keep = (
        (pts[:, 2] >= config.min_height)
        & (pts[:, 2] <= config.max_height)
        & (np.abs(bearing) <= half)
        & (horizontal > 0.0)
        & (horizontal <= config.max_range)
    )
    width = 2.0 * half / config.bins
    index = np.clip(np.floor((bearing[keep] + half) / width).astype(np.int64), 0, config.bins - 1)
    ranges = np.full(config.bins, np.inf, dtype=np.float64)
    np.minimum.at(ranges, index, horizontal[keep])
    centres = -half + (np.arange(config.bins, dtype=np.float64) + 0.5) * width
    return centres, ranges


def _wrap(angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles to ``[-pi, pi)``."""
    return np.asarray((angles + math.pi) % (2.0 * math.pi) - math.pi, dtype=np.float64)


class LidarOccupancy:
    """A log-odds occupancy grid in the episode frame built from field-of-view LiDAR rays (paper Sec. V-E).

    The grid covers the cells observed so far and grows when a ray leaves it. Each :meth:`update` casts one ray
    per bearing bin from the robot's position: the cell of a return gets ``hit`` once, every other cell a ray
    crosses before its return gets ``miss`` once (a cell both hit and crossed in one update counts as hit); a bin
    with no return is crossed up to ``max_range``. Clamping bounds the evidence, so an obstacle that moves away (a
    person walking by) is cleared after a few updates.
    """

    def __init__(self, config: LidarConfig | None = None) -> None:
        self.config = config or LidarConfig()
        self._logodds: NDArray[np.float32] = np.zeros((0, 0), dtype=np.float32)
        self._lower = (0, 0)  # lattice (row, col) of self._logodds[0, 0]

    def reset(self) -> None:
        """Forget every observation (a new episode)."""
        self._logodds = np.zeros((0, 0), dtype=np.float32)
        self._lower = (0, 0)

    def update(self, points: ArrayLike, pose: Pose, gimbal_yaw: float = 0.0) -> None:
        """Integrate one scan: ``points`` as in :func:`fov_ranges`, ``pose`` the robot base in the episode frame,
        ``gimbal_yaw`` the camera's yaw relative to the base."""
        bearings, ranges = fov_ranges(points, gimbal_yaw, self.config)
        angles = pose.yaw + gimbal_yaw + bearings
        crossed = self._crossed_cells(pose, angles, ranges)
        found = np.isfinite(ranges)
        hits = (
            self._lattice(pose.y + ranges[found] * np.sin(angles[found])),
            self._lattice(pose.x + ranges[found] * np.cos(angles[found])),
        )
        rows, cols = np.concatenate([crossed[0], hits[0]]), np.concatenate([crossed[1], hits[1]])
        low, high = (int(rows.min()), int(cols.min())), (int(rows.max()) + 1, int(cols.max()) + 1)
        self._cover(low, high)
        self._apply(
            self._region(low, high),
            (crossed[0] - low[0], crossed[1] - low[1]),
            (hits[0] - low[0], hits[1] - low[1]),
        )

    def window(self, pose: Pose) -> LocalOccupancy:
        """The ``window`` x ``window`` metre neighbourhood of the robot, its origin on a multiple of the
        resolution and the robot's cell at ``(n // 2, n // 2)`` of the ``n`` x ``n`` cells."""
        res = self.config.resolution
        n = max(1, round(self.config.window / res))
        row0 = math.floor(pose.y / res) - n // 2
        col0 = math.floor(pose.x / res) - n // 2
        cells = np.full((n, n), UNKNOWN_CELL, dtype=np.int8)
        rows, cols = self._logodds.shape
        low = (max(row0, self._lower[0]), max(col0, self._lower[1]))
        high = (min(row0 + n, self._lower[0] + rows), min(col0 + n, self._lower[1] + cols))
        if low[0] < high[0] and low[1] < high[1]:
            cells[low[0] - row0 : high[0] - row0, low[1] - col0 : high[1] - col0] = self._classify(
                self._region(low, high)
            )
        return LocalOccupancy(cells=cells, origin=(col0 * res, row0 * res), resolution=res)

    def _crossed_cells(
        self, pose: Pose, angles: NDArray[np.float64], ranges: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Lattice cells of samples every half cell along each ray, strictly before its return (or up to
        ``max_range`` where the bin has none)."""
        lengths = np.where(np.isfinite(ranges), ranges, self.config.max_range)
        steps = np.arange(0.0, self.config.max_range, self.config.resolution / 2.0)
        inside = steps[None, :] < lengths[:, None]
        xs = pose.x + steps[None, :] * np.cos(angles)[:, None]
        ys = pose.y + steps[None, :] * np.sin(angles)[:, None]
        return self._lattice(ys[inside]), self._lattice(xs[inside])

    def _lattice(self, coords: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.floor(coords / self.config.resolution).astype(np.int64)

    def _region(self, low: tuple[int, int], high: tuple[int, int]) -> NDArray[np.float32]:
        """A view of the stored lattice cells ``low <= (row, col) < high``."""
        r0, c0 = self._lower
        return self._logodds[low[0] - r0 : high[0] - r0, low[1] - c0 : high[1] - c0]

    def _cover(self, low: tuple[int, int], high: tuple[int, int]) -> None:
        """Grow the grid, with a ``max_range`` margin, until it stores the lattice cells ``low <= (row, col) <
        high``."""
        rows, cols = self._logodds.shape
        r0, c0 = self._lower
        if rows and r0 <= low[0] and c0 <= low[1] and high[0] <= r0 + rows and high[1] <= c0 + cols:
            return
        if rows:
            low = (min(low[0], r0), min(low[1], c0))
            high = (max(high[0], r0 + rows), max(high[1], c0 + cols))
        margin = math.ceil(self.config.max_range / self.config.resolution)
        grown = np.zeros((high[0] - low[0] + 2 * margin, high[1] - low[1] + 2 * margin), dtype=np.float32)
        lower = (low[0] - margin, low[1] - margin)
        grown[r0 - lower[0] : r0 - lower[0] + rows, c0 - lower[1] : c0 - lower[1] + cols] = self._logodds
        self._logodds, self._lower = grown, lower

    def _apply(
        self,
        box: NDArray[np.float32],
        crossed_cells: tuple[NDArray[np.int64], NDArray[np.int64]],
        hit_cells: tuple[NDArray[np.int64], NDArray[np.int64]],
    ) -> None:
        """Add ``miss`` once to every crossed cell and ``hit`` once to every return's cell of ``box`` (a view of
        the grid; cells as ``(rows, cols)`` within it), then clamp."""
        crossed = np.zeros(box.shape, dtype=bool)
        crossed[crossed_cells] = True
        hit = np.zeros(box.shape, dtype=bool)
        hit[hit_cells] = True
        crossed &= ~hit
        box[crossed] += np.float32(self.config.miss)
        box[hit] += np.float32(self.config.hit)
        np.clip(box, np.float32(self.config.clamp_min), np.float32(self.config.clamp_max), out=box)

    def _classify(self, evidence: NDArray[np.float32]) -> NDArray[np.int8]:
        cells = np.full(evidence.shape, UNKNOWN_CELL, dtype=np.int8)
        cells[evidence >= np.float32(self.config.occupied_threshold)] = OCCUPIED_CELL
        cells[evidence <= np.float32(self.config.free_threshold)] = FREE_CELL
        return cells
