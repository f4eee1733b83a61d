"""Depth + pose to obstacle, explored and navigable maps (paper Sec. IV-A a, the frontier-map pipeline).

Per update, every ``pixel_stride``-th row and column of the depth image is back-projected with the pinhole
intrinsics into the episode frame (camera level, at ``camera_height``, looking along the heading; a pixel
left of ``cx`` looks left, a pixel above ``cy`` looks up). Points in the obstacle height band mark obstacle
cells, and each new obstacle cell marks the disk of agent radius around it in an *inflated* map.

The explored map is a 2-D ray-cast of the horizontal field of view: each sampled image column gives the
distance to which it saw free space -- its nearest obstacle point; where it saw no obstacle, its farthest
floor-level evidence (a floor point, or a reading clipped at ``max_depth`` whose ray ends below the band top,
i.e. open floor out to the sensor range). A column with a reading clipped at ``min_depth`` (something too
close to measure) explores nothing. Rays fan out from the agent at most half a cell apart at the sensor
range (:func:`ray_fan`). The agent's own footprint is explored too. Space behind the first obstacle of a
column, including behind low furniture, stays unexplored until seen from elsewhere.

Derived on demand (:meth:`OccupancyMapper.snapshot`): ``explored`` is the 8-connected component of the
ray-cast map holding the agent; ``navigable`` is the 4-connected component of explored, non-inflated cells
holding the agent (or the nearest such cell when inflation covers the agent's own cell).

The grid starts ``initial_size`` metres square around the episode origin; before each update it is
re-allocated, ``growth_margin`` metres beyond what the sensor range needs, whenever that range would leave
the grid. Depth holes (NaN, inf, <= 0) are skipped; a frame of the wrong type or shape, or a non-finite
pose, is ignored whole.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.frontiers import component_at, extract_frontiers, nearest_in
from drivenav.mapping.kernels import cast_rays, project_depth, stamp
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.types import CameraIntrinsics, Pose

Mask = NDArray[np.bool_]
Box = tuple[int, int, int, int]  # row0, row1, col0, col1 (half-open)


@dataclass(frozen=True)
class UpdateInfo:
    """What the last :meth:`OccupancyMapper.update` did: ``reason`` says why a frame was ignored."""

    accepted: bool
    reason: str
    elapsed_ms: float
    new_obstacle_cells: int
    grew: bool


@dataclass(frozen=True)
class _Derived:
    """Explored / navigable maps restricted to ``box``, the part of the grid the sensor ever reached."""

    box: Box
    explored: Mask
    navigable: Mask


def disk_offsets(radius: float, resolution: float) -> NDArray[np.int64]:
    """Row/col offsets ``(N, 2)`` of the cells whose centres lie within ``radius`` of a cell's centre."""
    n = math.ceil(radius / resolution)
    di, dj = np.mgrid[-n : n + 1, -n : n + 1]
    inside = (di**2 + dj**2) * resolution**2 <= radius**2 + 1e-9
    return np.stack([di[inside], dj[inside]], axis=1).astype(np.int64)


def ray_fan(
    alphas: NDArray[np.float64], ranges: NDArray[np.float64], reach: float, resolution: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Evenly spaced ray angles over the columns' angles, at most half a cell apart at ``reach`` metres.

    Each ray takes the smaller range of the two sampled columns around it, so a coarse image never leaves gaps
    between rays far away and never explores past an obstacle seen by a neighbouring column.
    """
    order = np.argsort(alphas)
    a, r = alphas[order], ranges[order]
    if a.size < 2:
        return a, r
    n = max(a.size, math.ceil((a[-1] - a[0]) * reach / (0.5 * resolution)) + 1)
    fan = np.linspace(a[0], a[-1], n)
    k = np.clip(np.searchsorted(a, fan), 1, a.size - 1)
    return fan, np.minimum(r[k - 1], r[k])


class OccupancyMapper:
    """Accumulates obstacle and explored maps over an episode; see the module docstring for the model."""

    def __init__(self, config: MappingConfig | None = None) -> None:
        self.config = config if config is not None else MappingConfig()
        cfg = self.config
        self._disk = disk_offsets(cfg.agent_radius, cfg.resolution)  # the agent's footprint
        self._inflation = disk_offsets(self.inflation_radius, cfg.resolution)
        self._band = np.array(
            [cfg.min_depth, cfg.max_depth, cfg.clip_epsilon, cfg.min_obstacle_height, cfg.max_obstacle_height]
        )
        self.reset()

    @property
    def inflation_radius(self) -> float:
        """Obstacles are grown by this much (metres) to get the navigable map."""
        return self.config.agent_radius + self.config.inflation_margin

    def reset(self) -> None:
        """Forget everything: an empty grid of ``initial_size`` metres centred on the episode origin."""
        cfg = self.config
        n = math.ceil(cfg.initial_size / cfg.resolution)
        half = n * cfg.resolution / 2.0
        self._grid = GridSpec(cfg.resolution, (-half, -half), (n, n))
        self._obstacle: Mask = np.zeros((n, n), dtype=np.bool_)
        self._inflated: Mask = np.zeros((n, n), dtype=np.bool_)
        self._explored: Mask = np.zeros((n, n), dtype=np.bool_)
        self._pose = Pose(0.0, 0.0, 0.0)
        self._box: Box | None = None
        self._derived: _Derived | None = None
        self._frontiers: list[Frontier] | None = None
        self._last: UpdateInfo | None = None

    @property
    def grid(self) -> GridSpec:
        return self._grid

    @property
    def pose(self) -> Pose:
        """The pose of the last accepted update (the episode origin before any)."""
        return self._pose

    @property
    def last_update(self) -> UpdateInfo | None:
        return self._last

    def update(self, depth: NDArray[np.float32], intrinsics: CameraIntrinsics, pose: Pose) -> None:
        """Fuse one depth frame taken at ``pose``; bad input is ignored (see :attr:`last_update`)."""
        start = time.perf_counter()
        cfg = self.config
        rows = np.arange(0, intrinsics.height, cfg.pixel_stride, dtype=np.int64)
        cols = np.unique(np.r_[np.arange(0, intrinsics.width, cfg.pixel_stride), intrinsics.width - 1])
        kx = (intrinsics.cx - cols) / intrinsics.fx
        reach = cfg.max_depth * float(np.sqrt(1.0 + np.max(kx**2))) + cfg.resolution
        cover = reach + cfg.agent_radius + cfg.resolution  # obstacle hits and their inflation disks
        reason = _reject_reason(depth, intrinsics, pose) or self._too_far(pose, cover)
        if reason:
            self._last = UpdateInfo(False, reason, _ms_since(start), 0, False)
            return
        grew = self._ensure_covers(pose, cover)
        grid_params = np.array([*self._grid.origin, cfg.resolution])
        col_range = np.zeros(cols.size, dtype=np.float64)
        added = project_depth(
            np.ascontiguousarray(depth, dtype=np.float32),
            rows,
            cols,
            np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy, cfg.camera_height]),
            self._band,
            np.array([pose.x, pose.y, pose.yaw]),
            grid_params,
            self._obstacle,
            self._inflated,
            self._inflation,
            col_range,
        )
        position = np.array([pose.x, pose.y])
        alphas, ranges = ray_fan(np.arctan(kx), col_range, reach, cfg.resolution)
        cast_rays(position, pose.yaw + alphas, ranges, grid_params, self._explored)
        agent_row, agent_col = (int(v) for v in self._grid.world_to_cell(position))
        stamp(self._explored, agent_row, agent_col, self._disk)
        self._pose = pose
        self._extend_box(agent_row, agent_col, reach + cfg.pocket_window)
        self._derived = None
        self._frontiers = None
        self._last = UpdateInfo(True, "", _ms_since(start), added, grew)

    def snapshot(self) -> MapSnapshot:
        """Read-only copies of the current maps (see :class:`MapSnapshot`)."""
        derived = self._derive()
        explored = np.zeros_like(self._explored)
        navigable = np.zeros_like(self._explored)
        r0, r1, c0, c1 = derived.box
        explored[r0:r1, c0:c1] = derived.explored
        navigable[r0:r1, c0:c1] = derived.navigable
        obstacle = self._obstacle.copy()
        for array in (obstacle, explored, navigable):
            array.flags.writeable = False
        return MapSnapshot(self._grid, obstacle, explored, navigable)

    def frontiers(self) -> list[Frontier]:
        """Frontiers of the current maps whose pocket reaches ``min_frontier_area`` (cells in this grid)."""
        if self._frontiers is None:
            self._frontiers = self._extract_frontiers()
        return list(self._frontiers)

    def _extract_frontiers(self) -> list[Frontier]:
        derived = self._derive()
        r0, r1, c0, c1 = derived.box
        return extract_frontiers(
            self._grid,
            derived.explored,
            derived.navigable,
            self._inflated[r0:r1, c0:c1],
            min_area=self.config.min_frontier_area,
            pocket_window=self.config.pocket_window,
            offset=(r0, c0),
        )

    def _derive(self) -> _Derived:
        if self._derived is None:
            self._derived = self._compute_derived()
        return self._derived

    def _compute_derived(self) -> _Derived:
        if self._box is None:
            empty = np.zeros((0, 0), dtype=np.bool_)
            return _Derived((0, 0, 0, 0), empty, empty)
        r0, r1, c0, c1 = self._box
        row, col = (int(v) for v in self._grid.world_to_cell((self._pose.x, self._pose.y)))
        agent = (row - r0, col - c0)
        explored = component_at(self._explored[r0:r1, c0:c1], agent, eight=True)
        free = explored & ~self._inflated[r0:r1, c0:c1]
        search = math.ceil(self.inflation_radius / self.config.resolution) + 2
        seed = agent if free[agent] else nearest_in(free, agent, search)
        navigable = component_at(free, seed, eight=False) if seed is not None else np.zeros_like(free)
        return _Derived(self._box, explored, navigable)

    def _too_far(self, pose: Pose, reach: float) -> str:
        """Why the grid may not grow to cover ``pose`` ('' when it may): it would pass ``max_size``."""
        xmin, xmax, ymin, ymax = self._grid.extent
        side = max(xmax, pose.x + reach) - min(xmin, pose.x - reach)
        side = max(side, max(ymax, pose.y + reach) - min(ymin, pose.y - reach))
        if side + 2.0 * self.config.growth_margin > self.config.max_size:
            return f"pose ({pose.x:.1f}, {pose.y:.1f}) would grow the map past max_size"
        return ""

    def _ensure_covers(self, pose: Pose, reach: float) -> bool:
        """Grow the grid to hold the square of half-size ``reach`` around ``pose``; True if it grew."""
        grid = self._grid
        lo = grid.world_to_cell((pose.x - reach, pose.y - reach))
        hi = grid.world_to_cell((pose.x + reach, pose.y + reach))
        shape = np.array(grid.shape)
        if np.all(lo >= 0) and np.all(hi < shape):
            return False
        pad = math.ceil(self.config.growth_margin / grid.resolution)
        new_lo = np.where(lo < 0, lo - pad, 0)
        new_hi = np.where(hi >= shape, hi + pad + 1, shape)
        new_shape = (int(new_hi[0] - new_lo[0]), int(new_hi[1] - new_lo[1]))
        dr, dc = int(-new_lo[0]), int(-new_lo[1])
        for name in ("_obstacle", "_inflated", "_explored"):
            old: Mask = getattr(self, name)
            grown = np.zeros(new_shape, dtype=np.bool_)
            grown[dr : dr + old.shape[0], dc : dc + old.shape[1]] = old
            setattr(self, name, grown)
        origin = (grid.origin[0] - dc * grid.resolution, grid.origin[1] - dr * grid.resolution)
        self._grid = GridSpec(grid.resolution, origin, new_shape)
        if self._box is not None:
            b = self._box
            self._box = (b[0] + dr, b[1] + dr, b[2] + dc, b[3] + dc)
        return True

    def _extend_box(self, row: int, col: int, reach: float) -> None:
        """Add the square of half-size ``reach`` metres around cell ``(row, col)`` to the derived-map box."""
        n = math.ceil(reach / self._grid.resolution) + 1
        rows, cols = self._grid.shape
        box = (max(row - n, 0), min(row + n + 1, rows), max(col - n, 0), min(col + n + 1, cols))
        if self._box is not None:
            b = self._box
            box = (min(b[0], box[0]), max(b[1], box[1]), min(b[2], box[2]), max(b[3], box[3]))
        self._box = box


def _reject_reason(depth: object, intrinsics: CameraIntrinsics, pose: Pose) -> str:
    """Why a frame cannot be used ('' when it can)."""
    if not isinstance(depth, np.ndarray) or depth.dtype.kind != "f":
        return "depth is not a floating-point array"
    if depth.shape != (intrinsics.height, intrinsics.width):
        return f"depth shape {depth.shape} is not the intrinsics' ({intrinsics.height}, {intrinsics.width})"
    camera = (intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy)
    if not all(math.isfinite(v) for v in camera) or intrinsics.fx <= 0.0 or intrinsics.fy <= 0.0:
        return "intrinsics are not finite and positive"
    if not all(math.isfinite(v) for v in (pose.x, pose.y, pose.yaw)):
        return "pose is not finite"
    return ""


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1e3
