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

LiDAR (paper Sec. V-E: on the real robot, LiDAR + IMU give a 2-D occupancy grid keeping only the returns inside
the camera's forward 79 deg, Habitat's HFOV): :meth:`OccupancyMapper.fuse_occupancy` fuses such a window
(:class:`~drivenav.types.LocalOccupancy`; the agent calls it when ``fuse_lidar`` is set). Cells are matched by
their centres, so the window's resolution may differ a little from the map's and its origin be offset: a map cell
holding an occupied window cell's centre is marked in a LiDAR obstacle layer of its own; a map cell whose centre
lies in a free window cell is explored and cleared from that layer (a person who walked by), unless an occupied
window cell lands on it too; unknown cells change nothing. Depth obstacles are never cleared.
The LiDAR layer is inflated by the same disk, recomputed only around the window. The obstacles the rest of the
mapper uses (the snapshot's ``obstacle``, the inflation behind ``navigable``, frontier pockets) are the union of
the depth and LiDAR layers: with nothing fused, exactly the depth maps. A window whose resolution is not within
a factor 2 of the map's, or whose origin is not finite, is ignored whole.

The grid starts ``initial_size`` metres square around the episode origin; before each update it is
re-allocated, ``growth_margin`` metres beyond what the sensor range needs, whenever that range would leave
the grid. Depth holes (NaN, inf, <= 0) are skipped; a frame of the wrong type or shape, or a non-finite
pose, is ignored whole.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.frontiers import component_at, extract_frontiers, nearest_in
from drivenav.mapping.kernels import cast_rays, project_depth, stamp
from drivenav.mapping.stairs import NO_POINT, Relief, StairTuning, project_relief
from drivenav.mapping.types import Frontier, MapSnapshot, Rays
from drivenav.types import FREE_CELL, OCCUPIED_CELL, UNKNOWN_CELL, CameraIntrinsics, LocalOccupancy, Pose

Mask = NDArray[np.bool_]
Box = tuple[int, int, int, int]  # row0, row1, col0, col1 (half-open)


@functools.lru_cache(maxsize=8)
def _sampled_pixels(
    intrinsics: CameraIntrinsics, stride: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The depth pixels a frame is projected from -- every ``stride``-th row, every ``stride``-th column plus the
    last -- and each sampled column's ray slope ``(cx - u) / fx`` (read-only; the same for every frame)."""
    rows = np.arange(0, intrinsics.height, stride, dtype=np.int64)
    cols = np.unique(np.r_[np.arange(0, intrinsics.width, stride), intrinsics.width - 1])
    kx = (intrinsics.cx - cols) / intrinsics.fx
    for array in (rows, cols, kx):
        array.flags.writeable = False
    return rows, cols, kx


@dataclass(frozen=True)
class UpdateInfo:
    """What the last :meth:`OccupancyMapper.update` or :meth:`~OccupancyMapper.fuse_occupancy` did: ``reason``
    says why a frame or window was ignored."""

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


def disk_footprint(offsets: NDArray[np.int64]) -> Mask:
    """The square mask of ``offsets`` (from :func:`disk_offsets`) centred on its middle cell: a dilation structure
    that grows a mask exactly as stamping the disk around each set cell does."""
    n = int(np.abs(offsets).max())
    footprint = np.zeros((2 * n + 1, 2 * n + 1), dtype=np.bool_)
    footprint[offsets[:, 0] + n, offsets[:, 1] + n] = True
    return footprint


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

    def __init__(self, config: MappingConfig | None = None, stairs: StairTuning | None = None) -> None:
        self.config = config if config is not None else MappingConfig()
        self.stairs = stairs  # read stairs from depth too (mapping/stairs.py): a relief and drops layer
        cfg = self.config
        self._disk = disk_offsets(cfg.agent_radius, cfg.resolution)  # the agent's footprint
        self._inflation = disk_offsets(self.inflation_radius, cfg.resolution)
        self._footprint = disk_footprint(self._inflation)
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
        self._lidar_obstacle: Mask = np.zeros((n, n), dtype=np.bool_)
        self._lidar_inflated: Mask = np.zeros((n, n), dtype=np.bool_)
        self._top: NDArray[np.float32] = np.full((n, n) if self.stairs else (0, 0), NO_POINT, dtype=np.float32)
        self._drops: Mask = np.zeros((n, n) if self.stairs else (0, 0), dtype=np.bool_)
        self._pose = Pose(0.0, 0.0, 0.0)
        self._box: Box | None = None
        self._derived: _Derived | None = None
        self._frontiers: list[Frontier] | None = None
        self._last: UpdateInfo | None = None
        self._rays: Rays | None = None

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

    @property
    def last_rays(self) -> Rays | None:
        """The ray cast of the last depth frame fused (None before any): the cells it saw free."""
        return self._rays

    def update(self, depth: NDArray[np.float32], intrinsics: CameraIntrinsics, pose: Pose, rise: float = 0.0) -> None:
        """Fuse one depth frame taken at ``pose``, the agent ``rise`` metres above the map's floor (on the first step
        of a ramp, with floors on; heights are measured from the floor); bad input is ignored (see
        :attr:`last_update`)."""
        start = time.perf_counter()
        cfg = self.config
        rows, cols, kx = _sampled_pixels(intrinsics, cfg.pixel_stride)
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
            np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy, cfg.camera_height + rise]),
            self._band,
            np.array([pose.x, pose.y, pose.yaw]),
            grid_params,
            self._obstacle,
            self._inflated,
            self._inflation,
            col_range,
        )
        if self.stairs is not None:
            added += self._project_relief(depth, intrinsics, pose, rows, cols, grid_params, cfg.camera_height + rise)
        position = np.array([pose.x, pose.y])
        alphas, ranges = ray_fan(np.arctan(kx), col_range, reach, cfg.resolution)
        cast_rays(position, pose.yaw + alphas, ranges, grid_params, self._explored)
        self._rays = Rays(pose, alphas, ranges)
        agent_row, agent_col = (int(v) for v in self._grid.world_to_cell(position))
        stamp(self._explored, agent_row, agent_col, self._disk)
        self._pose = pose
        self._extend_box(agent_row, agent_col, reach + cfg.pocket_window)
        self._derived = None
        self._frontiers = None
        self._last = UpdateInfo(True, "", _ms_since(start), added, grew)

    def _project_relief(
        self,
        depth: NDArray[np.float32],
        intrinsics: CameraIntrinsics,
        pose: Pose,
        rows: NDArray[np.int64],
        cols: NDArray[np.int64],
        grid_params: NDArray[np.float64],
        camera_height: float,
    ) -> int:
        """Raise the relief and mark drops from the frame (:mod:`drivenav.mapping.stairs`); new drops are obstacles."""
        assert self.stairs is not None
        cfg = self.config
        return project_relief(
            np.ascontiguousarray(depth, dtype=np.float32),
            rows,
            cols,
            np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy, camera_height]),
            np.array([cfg.min_depth, cfg.max_depth, cfg.clip_epsilon, self.stairs.drop, self.stairs.max_height]),
            np.array([pose.x, pose.y, pose.yaw]),
            grid_params,
            self._top,
            self._drops,
            self._obstacle,
            self._inflated,
            self._inflation,
        )

    def relief(self) -> Relief | None:
        """The stair layers (None for a mapper that does not read stairs)."""
        if self.stairs is None:
            return None
        return Relief(self._grid, self._top, self._drops)

    def fuse_occupancy(self, local: LocalOccupancy) -> None:
        """Fuse a LiDAR occupancy window (paper Sec. V-E; module docstring); a bad window is ignored (see
        :attr:`last_update`). An occupied and a free window cell landing on the same mapper cell leave it occupied.
        """
        start = time.perf_counter()
        reason = _window_reject_reason(local, self.config.resolution) or self._too_far(*self._window_square(local))
        if reason:
            self._last = UpdateInfo(False, reason, _ms_since(start), 0, False)
            return
        centre, half = self._window_square(local)
        grew = self._ensure_covers(centre, half)
        box = self._window_box(local)
        added = self._mark_lidar(local, box)
        self._inflate_lidar(box)
        row, col = self._grid.cell_at(centre.x, centre.y)
        self._extend_box(row, col, half + self.config.pocket_window)
        self._derived = None
        self._frontiers = None
        self._last = UpdateInfo(True, "", _ms_since(start), added, grew)

    def _window_square(self, local: LocalOccupancy) -> tuple[Pose, float]:
        """Centre and half-size of the square the grid must hold for ``local``: the window and its inflation."""
        rows, cols = local.cells.shape
        centre = Pose(
            local.origin[0] + cols * local.resolution / 2.0, local.origin[1] + rows * local.resolution / 2.0, 0.0
        )
        half = max(rows, cols) * local.resolution / 2.0
        return centre, half + self.inflation_radius + self.config.resolution

    def _window_box(self, local: LocalOccupancy) -> Box:
        """The map cells the window overlaps."""
        rows, cols = local.cells.shape
        corner = (local.origin[0] + cols * local.resolution, local.origin[1] + rows * local.resolution)
        (r0, c0), (r1, c1) = (self._grid.world_to_cell(p) for p in (local.origin, corner))
        return int(r0), int(r1) + 1, int(c0), int(c1) + 1

    def _mark_lidar(self, local: LocalOccupancy, box: Box) -> int:
        """Clear and explore the map cells whose centre lies in a free window cell, then mark every map cell
        holding an occupied window cell's centre (no gaps in free space, no obstacle lost, whichever grid is the
        finer); the number of new LiDAR obstacle cells."""
        r0, r1, c0, c1 = box
        before = self._lidar_obstacle[r0:r1, c0:c1].copy()
        free = self._sample_window(local, box) == FREE_CELL
        self._lidar_obstacle[r0:r1, c0:c1] &= ~free
        self._explored[r0:r1, c0:c1] |= free
        hit_i, hit_j = np.nonzero(local.cells == OCCUPIED_CELL)
        centres = np.stack([hit_j + 0.5, hit_i + 0.5], axis=1) * local.resolution + np.array(local.origin)
        hits = self._grid.world_to_cell(centres)
        self._lidar_obstacle[hits[:, 0], hits[:, 1]] = True
        return int(np.count_nonzero(self._lidar_obstacle[r0:r1, c0:c1] & ~before))

    def _sample_window(self, local: LocalOccupancy, box: Box) -> NDArray[np.int8]:
        """The state of the window cell holding each map cell centre of ``box`` (unknown outside the window)."""
        r0, r1, c0, c1 = box
        res = self._grid.resolution
        ys = self._grid.origin[1] + (np.arange(r0, r1) + 0.5) * res
        xs = self._grid.origin[0] + (np.arange(c0, c1) + 0.5) * res
        i = np.floor((ys - local.origin[1]) / local.resolution).astype(np.int64)
        j = np.floor((xs - local.origin[0]) / local.resolution).astype(np.int64)
        rows, cols = local.cells.shape
        inside_i, inside_j = (i >= 0) & (i < rows), (j >= 0) & (j < cols)
        sampled = np.full((r1 - r0, c1 - c0), UNKNOWN_CELL, dtype=np.int8)
        sampled[np.ix_(inside_i, inside_j)] = local.cells[np.ix_(i[inside_i], j[inside_j])]
        return sampled

    def _inflate_lidar(self, box: Box) -> None:
        """Recompute the inflated LiDAR layer where obstacles changed inside ``box`` can reach: ``box`` grown by the
        inflation radius, dilating the LiDAR obstacles of ``box`` grown by twice that."""
        n = self._footprint.shape[0] // 2
        i0, i1, j0, j1 = self._pad(box, n)
        o0, o1, p0, p1 = self._pad(box, 2 * n)
        grown = ndimage.binary_dilation(self._lidar_obstacle[o0:o1, p0:p1], structure=self._footprint)
        self._lidar_inflated[i0:i1, j0:j1] = grown[i0 - o0 : i1 - o0, j0 - p0 : j1 - p0]

    def _pad(self, box: Box, n: int) -> Box:
        """``box`` grown by ``n`` cells on every side, clipped to the grid."""
        rows, cols = self._grid.shape
        return max(box[0] - n, 0), min(box[1] + n, rows), max(box[2] - n, 0), min(box[3] + n, cols)

    def _blocked(self, box: Box) -> Mask:
        """Cells of ``box`` within the inflation radius of a depth or LiDAR obstacle."""
        r0, r1, c0, c1 = box
        return self._inflated[r0:r1, c0:c1] | self._lidar_inflated[r0:r1, c0:c1]

    def snapshot(self) -> MapSnapshot:
        """Read-only copies of the current maps (see :class:`MapSnapshot`)."""
        derived = self._derive()
        explored = np.zeros_like(self._explored)
        navigable = np.zeros_like(self._explored)
        r0, r1, c0, c1 = derived.box
        explored[r0:r1, c0:c1] = derived.explored
        navigable[r0:r1, c0:c1] = derived.navigable
        obstacle = self._obstacle | self._lidar_obstacle
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
        r0, _, c0, _ = derived.box
        return extract_frontiers(
            self._grid,
            derived.explored,
            derived.navigable,
            self._blocked(derived.box),
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
        row, col = self._grid.cell_at(self._pose.x, self._pose.y)
        agent = (row - r0, col - c0)
        explored = component_at(self._explored[r0:r1, c0:c1], agent, eight=True)
        free = explored & ~self._blocked(self._box)
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
        layers = ["_obstacle", "_inflated", "_explored", "_lidar_obstacle", "_lidar_inflated"]
        for name in layers + (["_top", "_drops"] if self.stairs is not None else []):
            old: NDArray[np.generic] = getattr(self, name)
            grown = np.full(new_shape, NO_POINT if name == "_top" else False, dtype=old.dtype)
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


def _window_reject_reason(local: LocalOccupancy, resolution: float) -> str:
    """Why a LiDAR occupancy window cannot be fused onto a map of ``resolution`` ('' when it can)."""
    cells = local.cells
    if not isinstance(cells, np.ndarray) or cells.ndim != 2 or cells.dtype.kind not in "iu" or cells.size == 0:
        return "occupancy cells are not a non-empty 2-D integer array"
    if not (math.isfinite(local.resolution) and resolution / 2.0 <= local.resolution <= 2.0 * resolution):
        return f"occupancy resolution {local.resolution!r} is not within a factor 2 of the map's {resolution}"
    if not all(math.isfinite(v) for v in local.origin):
        return "occupancy origin is not finite"
    return ""


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1e3
