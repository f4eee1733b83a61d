"""VLFM's language-grounded value map (Yokoyama et al., "VLFM: Vision-Language Frontier Maps for Zero-Shot Semantic
Navigation", ICRA 2024; code bdaiinstitute/vlfm, ``vlfm/mapping/value_map.py``, class ``ValueMap``).

Every frame's image-text score is spread over the part of the floor the camera saw, on the mapper's grid
(:mod:`drivenav.grid` conventions), with a confidence per cell, and fused with what the cell already holds:

* Cone (``ValueMap._process_local_data`` / ``_get_blank_cone_mask``): the cells within the horizontal field of
  view, clipped per image column by the largest depth that column reads (VLFM squashes the depth image into one
  row of per-column maxima and fills the polygon they trace, at forward distance ``depth``). A cell at angle
  ``a`` off the optical axis belongs to the column a pinhole ray at ``a`` hits (VLFM spaces its columns' angles
  evenly over the FOV, an approximation of the same), and is visible when its forward distance ``r cos a`` is at
  most that column's depth. VLFM also cuts the cone at a circle of radius ``max_depth``, the area its obstacle map
  reveals; ours explores the whole depth frustum (:mod:`drivenav.mapping.occupancy`), out to
  ``max_depth / cos(fov / 2)`` at the image edge, so the cone is not cut there: every frontier borders cells the
  value map covers. The camera's own cell is left out (it has no direction).
* Confidence (``ValueMap._get_confidence_mask``): ``cos^2(a / (fov / 2) * pi / 2)`` -- 1 on the optical axis, 0 at
  the edge of the FOV -- remapped linearly from ``[0, 1]`` to ``[min_confidence, 1]``.
* Fusion (``ValueMap._fuse_new_data``, VLFM's default fusion with ``use_max_confidence=False``, the setting of
  ``VLFMConfig`` in ``vlfm/policy/base_objectnav_policy.py``): a new confidence below ``decision_threshold`` and
  below the cell's is dropped (the cell is unchanged); otherwise
  ``v = (c_old v_old + c_new s) / (c_old + c_new)`` and ``c = (c_old^2 + c_new^2) / (c_old + c_new)``.
* Value at a point (``ValueMap.sort_waypoints`` with ``vlfm/utils/img_utils.py`` ``pixel_value_within_radius``,
  radius 0.5 m in ``ITMPolicyV2._sort_frontiers_by_value``): the median value of the seen cells within
  ``frontier_radius`` (a disk of ``int(radius / resolution)`` cells), ``UNSEEN_VALUE`` (-1) when none is seen. VLFM
  keeps the non-zero cells, which for its positive BLIP-2 cosines are the cells seen; here "seen" is "confidence
  above 0", so a scorer's 0 or negative score still counts.

ApexNav (Zhang et al., RA-L 2025; ``value_map2d.cpp``) keeps VLFM's rule with two changes, both settings here:
its confidence is the bare ``cos^2`` (``min_confidence`` 0) and no new data is dropped (``decision_threshold`` 0);
and it writes a frame's score onto the cells that frame's 2-D ray cast saw free, not onto a cone
(:meth:`ValueMap.update_rays`, from the mapper's rays, :class:`~drivenav.mapping.types.Rays`). Its fusion has no
guard for a cell and a new confidence both 0 (at the edge of the FOV); here such a cell is left unchanged.

The grid follows the mapper's, which grows during an episode (:meth:`ValueMap.follow`). The cone's geometry per
cell offset (distance and bearing from the camera's cell) is computed once per map, so an update is a few
vectorised passes over the cells of one disk of ``max_depth`` radius.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivenav.grid import GridSpec
from drivenav.mapping.types import Rays
from drivenav.ranges import LENGTH, Range, check_declared
from drivenav.types import CameraIntrinsics, Pose

FloatMap = NDArray[np.float64]

UNSEEN_VALUE = -1.0
"""The value at a point with no seen cell near it (``img_utils.py`` ``pixel_value_within_radius`` returns -1): below
every score of the scorers (cosines, probabilities). A constant, not a setting: the configuration's numbers are
all >= 0."""


@dataclass(frozen=True)
class ValueMapConfig:
    """VLFM's constants (bdaiinstitute/vlfm): the value map's and those of its frontier choice
    (:mod:`drivenav.agent.explorers.vlfm.explorer`)."""

    min_confidence: float = 0.25  # value_map.py ValueMap._min_confidence: the confidence at the FOV's edge
    decision_threshold: float = 0.35  # value_map.py ValueMap._decision_threshold: weaker new data is dropped ...
    # ... where the cell is already more confident (ValueMap._fuse_new_data)
    frontier_radius: float = 0.5  # itm_policy.py ITMPolicyV2._sort_frontiers_by_value: sort_waypoints(frontiers, 0.5)
    keep_radius: float = 0.5  # itm_policy.py BaseITMPolicy._get_best_frontier: the last frontier is still there ...
    # ... if a frontier point lies within this many metres of it (closest_point_within_threshold(..., 0.5))
    keep_margin: float = 0.01  # itm_policy.py BaseITMPolicy._get_best_frontier: keep it while value + 0.01 > last

    RANGES: ClassVar[Mapping[str, Range]] = {
        "min_confidence": Range(0.0, 1.0, high_open=True, why="a confidence, below the optical axis's 1"),
        "decision_threshold": Range(0.0, 1.0, why="a confidence"),
        "frontier_radius": LENGTH,
        "keep_radius": LENGTH,
        "keep_margin": Range(0.0, 2.0, why="a difference of two scores in [-1, 1]"),
    }

    def __post_init__(self) -> None:
        check_declared(self)


@dataclass(frozen=True)
class _Cone:
    """The cells within ``reach`` of the camera's cell (itself excluded), sorted by bearing: row/col offsets,
    world offsets ``dx, dy`` (metres), bearing (radians, ``[-pi, pi]``) and distance of each, for one resolution and
    reach."""

    rows: NDArray[np.int64]
    cols: NDArray[np.int64]
    extent: int  # the largest |row| or |col| offset
    dx: FloatMap
    dy: FloatMap
    bearing: FloatMap
    distance: FloatMap

    @staticmethod
    def build(resolution: float, reach: float) -> _Cone:
        n = math.ceil(reach / resolution)
        di, dj = np.mgrid[-n : n + 1, -n : n + 1]
        distance = np.hypot(di, dj) * resolution
        inside = (distance <= reach) & (distance > 0.0)
        rows, cols = di[inside], dj[inside]
        bearing = np.arctan2(rows, cols).astype(np.float64)
        order = np.argsort(bearing, kind="stable")
        rows, cols = rows[order], cols[order]
        return _Cone(rows, cols, n, cols * resolution, rows * resolution, bearing[order], distance[inside][order])

    def within(self, yaw: float, half_fov: float) -> tuple[slice | NDArray[np.int64], FloatMap]:
        """The cells whose bearing lies within ``half_fov`` of ``yaw`` (a slice of the cells, or their indices where
        the range wraps past pi), and their signed angle off ``yaw``."""
        lo, hi = yaw - half_fov, yaw + half_fov
        shift = 2.0 * math.pi * math.floor((lo + math.pi) / (2.0 * math.pi))  # brings lo into [-pi, pi)
        lo, hi, yaw = lo - shift, hi - shift, yaw - shift
        first = slice(int(np.searchsorted(self.bearing, lo)), int(np.searchsorted(self.bearing, hi, "right")))
        if hi <= math.pi:
            return first, self.bearing[first] - yaw
        wrapped = slice(0, int(np.searchsorted(self.bearing, hi - 2.0 * math.pi, "right")))
        index = np.r_[np.arange(first.start, first.stop), np.arange(wrapped.start, wrapped.stop)]
        return index, np.r_[self.bearing[first] - yaw, self.bearing[wrapped] + (2.0 * math.pi - yaw)]


class ValueMap:
    """A value map and its confidence map on a grid (module docstring). ``value`` and ``confidence`` are
    ``[row, col]`` arrays of the grid's shape; a cell never seen has confidence 0."""

    def __init__(self, grid: GridSpec, max_depth: float, config: ValueMapConfig | None = None) -> None:
        if not (math.isfinite(max_depth) and max_depth > 0.0):
            raise ValueError(f"ValueMap needs a positive finite max_depth, got {max_depth!r}")
        self.config = config or ValueMapConfig()
        self.max_depth = max_depth
        self._grid = grid
        self.value: FloatMap = np.zeros(grid.shape, dtype=np.float64)
        self.confidence: FloatMap = np.zeros(grid.shape, dtype=np.float64)
        self._cones: dict[float, _Cone] = {}  # by reach (one per camera, in practice)
        n = int(self.config.frontier_radius / grid.resolution)  # VLFM: int(radius * pixels_per_meter)
        di, dj = np.mgrid[-n : n + 1, -n : n + 1]
        disk = di**2 + dj**2 <= n**2
        self._disk = (di[disk], dj[disk])

    @property
    def grid(self) -> GridSpec:
        return self._grid

    def follow(self, grid: GridSpec) -> None:
        """Move onto ``grid``, the mapper's grid after it grew (same resolution, origin shifted by whole cells):
        what the map holds stays at its world position."""
        old = self._grid
        if grid == old:
            return
        if not math.isclose(grid.resolution, old.resolution):
            raise ValueError(f"ValueMap: grid resolution {grid.resolution} is not the map's {old.resolution}")
        dr = round((old.origin[1] - grid.origin[1]) / grid.resolution)
        dc = round((old.origin[0] - grid.origin[0]) / grid.resolution)
        self.value = _moved(self.value, grid.shape, dr, dc)
        self.confidence = _moved(self.confidence, grid.shape, dr, dc)
        self._grid = grid

    def update(self, score: float, pose: Pose, depth: NDArray[np.floating], intrinsics: CameraIntrinsics) -> None:
        """Spread ``score`` over the cells the camera at ``pose`` saw in ``depth`` (z-depth in metres, clipped to
        ``max_depth``; holes -- NaN, inf, <= 0 -- read as nothing seen in their column) and fuse it in.
        A non-finite score or pose, or a frame that does not match ``intrinsics``, changes nothing."""
        if not (math.isfinite(score) and math.isfinite(pose.x) and math.isfinite(pose.y) and math.isfinite(pose.yaw)):
            return
        if depth.shape != (intrinsics.height, intrinsics.width):
            return
        cells, confidence = self.cone_cells(pose, _column_depths(depth), intrinsics)
        self._fuse(cells, confidence, score)

    def update_rays(self, score: float, rays: Rays, intrinsics: CameraIntrinsics) -> None:
        """Fuse ``score`` into the cells the frame's ray cast saw free (ApexNav's update, module docstring): the
        cells within the FOV strictly nearer than the range of the ray nearest in angle. A non-finite score or
        pose, or no rays, changes nothing."""
        pose = rays.pose
        if not (math.isfinite(score) and math.isfinite(pose.x) and math.isfinite(pose.y) and math.isfinite(pose.yaw)):
            return
        if rays.angles.size == 0:
            return
        cells, confidence = self.ray_cells(rays, intrinsics)
        self._fuse(cells, confidence, score)

    def ray_cells(self, rays: Rays, intrinsics: CameraIntrinsics) -> tuple[NDArray[np.int64], FloatMap]:
        """The grid cells the ray cast saw free (flat indices into the ``[row, col]`` maps) and their confidence; the
        rays are evenly spaced in angle (:func:`~drivenav.mapping.occupancy.ray_fan`)."""
        half_fov = math.atan2(intrinsics.width / 2.0, intrinsics.fx)
        pose = rays.pose
        cone = self._cone(self.max_depth / math.cos(half_fov))
        index, angle = cone.within(pose.yaw, half_fov)
        angles, last = rays.angles, rays.angles.size - 1
        span = float(angles[-1] - angles[0])
        ray = np.zeros(angle.shape, dtype=np.int64)
        if last > 0 and span > 0.0:  # evenly spaced rays: the nearest by rounding
            ray = np.clip(np.rint((angle - angles[0]) * (last / span)), 0, last).astype(np.int64)
        visible = cone.distance[index] < rays.ranges[ray]
        return self._placed(cone, index, angle, visible, pose, half_fov)

    def cone_cells(
        self, pose: Pose, column_depth: FloatMap, intrinsics: CameraIntrinsics
    ) -> tuple[NDArray[np.int64], FloatMap]:
        """The grid cells of the visible FOV cone from ``pose`` (flat indices into the ``[row, col]`` maps) and their
        confidence, given each image column's largest depth ``column_depth`` (``(width,)``, NaN where the column
        read nothing)."""
        half_fov = math.atan2(intrinsics.width / 2.0, intrinsics.fx)  # vlfm geometry_utils.get_fov(fx, width) / 2
        cone = self._cone(self.max_depth / math.cos(half_fov))
        index, angle = cone.within(pose.yaw, half_fov)
        cos, sin = math.cos(pose.yaw), math.sin(pose.yaw)
        dx, dy = cone.dx[index], cone.dy[index]
        forward = dx * cos + dy * sin  # camera frame: ahead (> 0 within the FOV) ...
        slope = (dy * cos - dx * sin) / forward  # ... and to the left, per metre ahead
        column = np.clip(np.rint(intrinsics.cx - intrinsics.fx * slope), 0, intrinsics.width - 1).astype(np.int64)
        visible = forward <= column_depth[column]  # NaN compares False
        return self._placed(cone, index, angle, visible, pose, half_fov)

    def _placed(
        self,
        cone: _Cone,
        index: slice | NDArray[np.int64],
        angle: FloatMap,
        visible: NDArray[np.bool_],
        pose: Pose,
        half_fov: float,
    ) -> tuple[NDArray[np.int64], FloatMap]:
        """The ``visible`` cone cells placed at ``pose`` (flat indices; those off the grid left out) and their
        confidence: ``cos^2`` of their angle off the axis over the FOV, remapped to ``[min_confidence, 1]``."""
        cfg = self.config
        rows, cols = self._grid.shape
        row0, col0 = self._grid.cell_at(pose.x, pose.y)
        cell_rows, cell_cols = cone.rows[index] + row0, cone.cols[index] + col0
        if not (cone.extent <= row0 < rows - cone.extent and cone.extent <= col0 < cols - cone.extent):
            visible &= (cell_rows >= 0) & (cell_rows < rows) & (cell_cols >= 0) & (cell_cols < cols)
        falloff = np.cos(angle[visible] * (math.pi / 2.0 / half_fov)) ** 2
        flat = cell_rows[visible] * cols + cell_cols[visible]
        return flat, cfg.min_confidence + (1.0 - cfg.min_confidence) * falloff

    def _cone(self, reach: float) -> _Cone:
        if reach not in self._cones:
            self._cones[reach] = _Cone.build(self._grid.resolution, reach)
        return self._cones[reach]

    def _fuse(self, cells: NDArray[np.int64], new: FloatMap, score: float) -> None:
        """VLFM's confidence-weighted fusion of ``score`` at ``new`` confidence into the cells (flat indices;
        module docstring)."""
        value, confidence = self.value.reshape(-1), self.confidence.reshape(-1)  # views of the maps
        old = confidence[cells]
        kept = ((new >= self.config.decision_threshold) | (new >= old)) & (old + new > 0.0)
        cells, new, old = cells[kept], new[kept], old[kept]
        total = old + new
        value[cells] = (old * value[cells] + new * score) / total
        confidence[cells] = (old * old + new * new) / total

    def value_at(self, points: ArrayLike) -> FloatMap:
        """The value at each world point ``(N, 2)``: the median over the seen cells within ``frontier_radius``
        (:data:`UNSEEN_VALUE` where none is seen)."""
        cells = self._grid.world_to_cell(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        rows = cells[:, :1] + self._disk[0]
        cols = cells[:, 1:] + self._disk[1]
        inside = (rows >= 0) & (rows < self._grid.shape[0]) & (cols >= 0) & (cols < self._grid.shape[1])
        rows, cols = np.where(inside, rows, 0), np.where(inside, cols, 0)
        seen = inside & (self.confidence[rows, cols] > 0.0)
        values = np.where(seen, self.value[rows, cols], np.nan)
        out = np.full(len(cells), UNSEEN_VALUE)
        any_seen = seen.any(axis=1)
        if any_seen.any():
            out[any_seen] = np.nanmedian(values[any_seen], axis=1)
        return out


def _column_depths(depth: NDArray[np.floating]) -> FloatMap:
    """Each image column's largest valid depth (VLFM's ``np.max(depth, axis=0)``); NaN where the column has none.
    Holes (NaN, inf, <= 0) are skipped: a column of holes <= 0 only keeps a maximum <= 0, which no cell ahead of the
    camera is within."""
    row: FloatMap = depth.max(axis=0).astype(np.float64)
    if np.isfinite(row).all():
        return row
    cleaned = np.where(np.isfinite(depth) & (depth > 0.0), depth, np.nan)
    valid = ~np.isnan(cleaned).all(axis=0)
    out = np.full(depth.shape[1], np.nan)
    out[valid] = np.nanmax(cleaned[:, valid], axis=0)
    return out


def _moved(array: FloatMap, shape: tuple[int, int], dr: int, dc: int) -> FloatMap:
    """``array`` placed at row/col offset ``(dr, dc)`` in a zero array of ``shape`` (what falls outside is cut)."""
    out = np.zeros(shape, dtype=array.dtype)
    r0, c0 = max(dr, 0), max(dc, 0)
    r1, c1 = min(dr + array.shape[0], shape[0]), min(dc + array.shape[1], shape[1])
    if r1 > r0 and c1 > c0:
        out[r0:r1, c0:c1] = array[r0 - dr : r1 - dr, c0 - dc : c1 - dc]
    return out
