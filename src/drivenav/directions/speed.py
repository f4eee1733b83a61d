"""The weighted-FMM speed field F = F_obs * F_vor on a cropped window of the map (Sec. IV-A a, Eqs. 1-3).

Traversability. FMM paths may only run through *traversable* cells: navigable cells plus the cells of the given
frontiers (frontier cells lie on the navigable/unexplored boundary; whichever side of it the mapping module puts
them on, they must be reachable), minus obstacle cells. Unexplored cells are *not* traversable: a path-induced
bearing should describe how the known free space leads towards a frontier, not a shortcut through unseen space.
Non-traversable cells get speed 0 (infinite cost).

Skeleton. The medial skeleton is taken with respect to the obstacles: the pruned integer medial axis of the
obstacle feature transform (the ridge of ``d_obs``), restricted to navigable cells. The boundary between
explored and unexplored space does not spawn skeleton branches -- it moves every step and says nothing about
where the free space's centre lines are -- and one feature transform serves both ``d_obs`` and the skeleton.

Cropping. Everything is computed on the bounding box of the traversable and obstacle cells plus a small margin.
Because every obstacle and every navigable cell lies inside the window, ``d_obs``, the skeleton and ``d_vor``
are exactly what the full map would give.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.edt import IncrementalTransform, changed_rows, feature_transform, squared_edt
from drivenav.directions.timing import elapsed_ms
from drivenav.grid import GridSpec
from drivenav.jit import jit
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import SpeedFieldConfig

ScalarT = TypeVar("ScalarT", bound=np.generic)

CROP_MARGIN = 2  # cells around the bounding box of the traversable and obstacle cells
TABLE_TOLERANCE = 1e-6  # exponential terms below this are replaced by their asymptote


@dataclass(frozen=True)
class Window:
    """A crop ``[r0:r1, c0:c1]`` of a map grid, with its own :class:`GridSpec`."""

    r0: int
    c0: int
    r1: int
    c1: int
    grid: GridSpec

    @property
    def slices(self) -> tuple[slice, slice]:
        return slice(self.r0, self.r1), slice(self.c0, self.c1)


@dataclass(frozen=True)
class SpeedField:
    """The speed field on a window; ``speed`` is 0 on non-traversable cells.

    ``obstacle_sq`` / ``skeleton_sq`` are squared distances in cells^2 to the nearest obstacle / skeleton cell
    (``inf`` where there is none, and everywhere in the uniform-speed ablation).
    """

    window: Window
    traversable: NDArray[np.bool_]
    obstacle_sq: NDArray[np.float64]
    skeleton: NDArray[np.bool_]
    skeleton_sq: NDArray[np.float64]
    speed: NDArray[np.float64]
    timings_ms: dict[str, float]

    @property
    def d_obs(self) -> NDArray[np.float64]:
        """Distance to the nearest obstacle in metres."""
        return np.asarray(np.sqrt(self.obstacle_sq) * self.window.grid.resolution, dtype=np.float64)

    @property
    def d_vor(self) -> NDArray[np.float64]:
        """Distance to the medial skeleton in metres."""
        return np.asarray(np.sqrt(self.skeleton_sq) * self.window.grid.resolution, dtype=np.float64)


def traversable_mask(snapshot: MapSnapshot, frontiers: Sequence[Frontier]) -> NDArray[np.bool_]:
    """Navigable cells plus in-grid frontier cells, minus obstacles (see the module docstring)."""
    trav = np.array(snapshot.navigable, dtype=np.bool_)
    if frontiers:
        cells = np.concatenate([frontier.cells for frontier in frontiers])
        cells = cells[snapshot.grid.contains(cells)]
        trav[cells[:, 0], cells[:, 1]] = True
    trav &= ~snapshot.obstacle
    return trav


def crop_window(grid: GridSpec, keep: NDArray[np.bool_], margin: int = CROP_MARGIN) -> Window:
    """The bounding box of ``keep`` grown by ``margin`` cells and clipped to the grid (the whole grid if empty)."""
    rows_any = np.flatnonzero(keep.any(axis=1))
    cols_any = np.flatnonzero(keep.any(axis=0))
    if rows_any.size == 0:
        return _clipped(grid, 0, 0, grid.shape[0], grid.shape[1])
    r0, r1 = int(rows_any[0]) - margin, int(rows_any[-1]) + margin + 1
    return _clipped(grid, r0, int(cols_any[0]) - margin, r1, int(cols_any[-1]) + margin + 1)


def _clipped(grid: GridSpec, r0: int, c0: int, r1: int, c1: int) -> Window:
    """The window ``[r0:r1, c0:c1]`` of ``grid`` clipped to it, with its own grid spec."""
    r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1, grid.shape[0]), min(c1, grid.shape[1])
    res = grid.resolution
    origin = (grid.origin[0] + c0 * res, grid.origin[1] + r0 * res)
    return Window(r0, c0, r1, c1, GridSpec(res, origin, (r1 - r0, c1 - c0)))


@jit("void(b1[:, ::1], f8[:, ::1], i4[:, ::1], i4[:, ::1], f8, f8, b1[::1], b1[:, ::1])")
def _medial_axis_rows(
    inside: NDArray[np.bool_],
    sq: NDArray[np.float64],
    frow: NDArray[np.int32],
    fcol: NDArray[np.int32],
    min_sep: float,
    angle_ratio: float,
    rows_to_do: NDArray[np.bool_],
    out: NDArray[np.bool_],
) -> None:
    """The skeleton marks of the rows in ``rows_to_do``, written into ``out`` (other rows are left alone)."""
    rows, cols = inside.shape
    for i in range(rows):
        if rows_to_do[i]:
            out[i, :] = False
    for i in range(rows):
        if not (rows_to_do[i] or (i + 1 < rows and rows_to_do[i + 1])):
            continue
        for j in range(cols):
            if not inside[i, j]:
                continue
            for di, dj in ((0, 1), (1, 0)):
                qi, qj = i + di, j + dj
                if qi >= rows or qj >= cols or not inside[qi, qj] or not (rows_to_do[i] or rows_to_do[qi]):
                    continue
                dr = float(frow[i, j] - frow[qi, qj])
                dc = float(fcol[i, j] - fcol[qi, qj])
                sep2 = dr * dr + dc * dc
                depth2 = max(sq[i, j], sq[qi, qj])
                if sep2 < min_sep * min_sep or sep2 < angle_ratio * angle_ratio * depth2:
                    continue
                # Mark the cell of the pair nearer the bisector of the two features (Hesselink & Roerdink).
                side = (i + qi - frow[i, j] - frow[qi, qj]) * dr + (j + qj - fcol[i, j] - fcol[qi, qj]) * dc
                if side <= 0 and rows_to_do[i]:
                    out[i, j] = True
                if side >= 0 and rows_to_do[qi]:
                    out[qi, qj] = True


def medial_skeleton(
    region: NDArray[np.bool_],
    sq: NDArray[np.float64],
    frow: NDArray[np.int32],
    fcol: NDArray[np.int32],
    min_separation: float = SpeedFieldConfig.skeleton_min_separation,
    angle_ratio: float = SpeedFieldConfig.skeleton_min_angle_ratio,
) -> NDArray[np.bool_]:
    """The medial skeleton of ``region`` w.r.t. the features of a feature transform: a pruned integer medial
    axis (Hesselink & Roerdink, 2008).

    ``sq``, ``frow``, ``fcol`` are :func:`feature_transform` outputs. Two 4-adjacent region cells whose
    nearest features are at least ``min_separation`` cells apart and subtend a large enough angle
    (``|f(p) - f(q)| >= angle_ratio * distance``) straddle the medial axis; the one nearer the bisector of
    the two features is marked.
    """
    out = np.zeros(region.shape, np.bool_)
    every_row = np.ones(region.shape[0], np.bool_)
    _medial_axis_rows(region, sq, frow, fcol, min_separation, angle_ratio, every_row, out)
    return out


def speed_from_distances(
    d_obs: NDArray[np.float64], d_vor: NDArray[np.float64], config: SpeedFieldConfig
) -> NDArray[np.float64]:
    """Eqs. 1-3: ``(1 - lam exp(-d_obs / r_obs)) * (1 + beta exp(-d_vor / r_vor))`` (distances in metres)."""
    return np.asarray(_f_obs(d_obs, config) * _f_vor(d_vor, config), dtype=np.float64)


def _f_obs(d: NDArray[np.float64], config: SpeedFieldConfig) -> NDArray[np.float64]:
    return np.asarray(1.0 - config.lam * np.exp(-d / config.r_obs), dtype=np.float64)


def _f_vor(d: NDArray[np.float64], config: SpeedFieldConfig) -> NDArray[np.float64]:
    return np.asarray(1.0 + config.beta * np.exp(-d / config.r_vor), dtype=np.float64)


def _squared_distance_table(
    factor: Callable[[NDArray[np.float64], SpeedFieldConfig], NDArray[np.float64]],
    config: SpeedFieldConfig,
    rate: float,
    amplitude: float,
    resolution: float,
) -> NDArray[np.float64]:
    """``factor`` sampled at every integer squared distance (cells^2) up to where its exponential term drops
    below ``TABLE_TOLERANCE``; the last entry holds the asymptote and serves every farther cell."""
    far_cells = rate * math.log(max(amplitude, TABLE_TOLERANCE) / TABLE_TOLERANCE) / resolution
    sq = np.arange(math.ceil(far_cells * far_cells) + 2, dtype=np.float64)
    table = factor(np.sqrt(sq) * resolution, config)
    table[-1] = factor(np.array([np.inf]), config)[0]
    return table


@jit("void(b1[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], b1[::1], f8[:, ::1])")
def _speed_rows(
    trav: NDArray[np.bool_],
    obstacle_sq: NDArray[np.float64],
    skeleton_sq: NDArray[np.float64],
    obs_table: NDArray[np.float64],
    vor_table: NDArray[np.float64],
    rows_to_do: NDArray[np.bool_],
    out: NDArray[np.float64],
) -> None:
    """The speed of the rows in ``rows_to_do``, written into ``out`` (0 off the traversable cells)."""
    rows, cols = trav.shape
    last_obs = obs_table.size - 1
    last_vor = vor_table.size - 1
    for i in range(rows):
        if not rows_to_do[i]:
            continue
        for j in range(cols):
            speed = 0.0
            if trav[i, j]:
                a = obstacle_sq[i, j]
                b = skeleton_sq[i, j]
                ka = last_obs if a >= last_obs else int(a)
                kb = last_vor if b >= last_vor else int(b)
                speed = obs_table[ka] * vor_table[kb]
            out[i, j] = speed


def weighted_speed(
    trav: NDArray[np.bool_],
    obstacle_sq: NDArray[np.float64],
    skeleton_sq: NDArray[np.float64],
    config: SpeedFieldConfig,
    resolution: float,
) -> NDArray[np.float64]:
    """Eqs. 1-3 on the traversable cells, from squared cell distances, via lookup tables built once per configuration
    and resolution (squared distances on a grid are integers, so a table lookup is exact and much cheaper than two
    exponentials)."""
    obs, vor = _speed_tables(config, resolution)
    out = np.empty(trav.shape, np.float64)
    _speed_rows(trav, obstacle_sq, skeleton_sq, obs, vor, np.ones(trav.shape[0], np.bool_), out)
    return out


@functools.lru_cache(maxsize=8)
def _speed_tables(config: SpeedFieldConfig, resolution: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The obstacle and skeleton lookup tables, built once per configuration and resolution (read-only)."""
    obs = _squared_distance_table(_f_obs, config, config.r_obs, config.lam, resolution)
    vor = _squared_distance_table(_f_vor, config, config.r_vor, config.beta, resolution)
    for table in (obs, vor):
        table.flags.writeable = False
    return obs, vor


def build_speed_field(snapshot: MapSnapshot, frontiers: Sequence[Frontier], config: SpeedFieldConfig) -> SpeedField:
    """Crop, traversability, distance transforms, skeleton and speed (uniform 1 if ``config.weighted`` is off).

    ``timings_ms`` holds ``distance_transforms`` (including cropping and the speed itself) and ``skeleton``.
    """
    t0 = time.perf_counter()
    trav_full = traversable_mask(snapshot, frontiers)
    window = crop_window(snapshot.grid, trav_full | snapshot.obstacle)
    rs, cs = window.slices
    trav = np.ascontiguousarray(trav_full[rs, cs])
    if not config.weighted:
        far = np.full(trav.shape, np.inf)
        speed = np.where(trav, 1.0, 0.0)
        timings = {"distance_transforms": elapsed_ms(t0), "skeleton": 0.0}
        return SpeedField(window, trav, far, np.zeros(trav.shape, np.bool_), far, speed, timings)
    obstacle_sq, frow, fcol = feature_transform(snapshot.obstacle[rs, cs])
    t1 = time.perf_counter()
    region = trav & snapshot.navigable[rs, cs]
    skeleton = medial_skeleton(
        region, obstacle_sq, frow, fcol, config.skeleton_min_separation, config.skeleton_min_angle_ratio
    )
    t2 = time.perf_counter()
    skeleton_sq = squared_edt(skeleton)
    speed = weighted_speed(trav, obstacle_sq, skeleton_sq, config, window.grid.resolution)
    timings = {
        "distance_transforms": (t1 - t0) * 1e3 + elapsed_ms(t2),
        "skeleton": (t2 - t1) * 1e3,
    }
    return SpeedField(window, trav, obstacle_sq, skeleton, skeleton_sq, speed, timings)


# Cells kept around the crop window by SpeedFieldBuilder, so that a growing map rarely outgrows them.
CAPACITY_MARGIN = 16


class SpeedFieldBuilder:
    """:func:`build_speed_field` for the successive maps of one episode, kept up to date instead of recomputed:
    the same arrays, bit for bit.

    The obstacle feature transform, the skeleton, the skeleton distance transform and the speed are kept on a
    *capacity* window (the crop window grown by ``CAPACITY_MARGIN`` cells). Each build redoes only what the map's
    change reaches: the transforms' changed columns and rows (:class:`IncrementalTransform`), the skeleton rows next
    to rows whose feature transform or region changed, and the speed rows whose inputs changed. Computing on a larger
    window than the crop gives the same numbers (every obstacle and traversable cell lies inside the crop, and the
    transforms' integer arithmetic is exact under a shift), so the crop of the kept arrays is
    :func:`build_speed_field`'s result. The capacity window is anchored in the world: a grid that grew (the mapper
    adds cells around its map) keeps it; a crop outside it, or another resolution, starts over.
    """

    def __init__(self, config: SpeedFieldConfig) -> None:
        self._config = config
        self._kept: _KeptField | None = None

    def reset(self) -> None:
        """Forget the kept arrays (a new episode)."""
        self._kept = None

    def build(self, snapshot: MapSnapshot, frontiers: Sequence[Frontier]) -> SpeedField:
        """The speed field of this map and frontiers (see :func:`build_speed_field`).

        ``speed`` and ``traversable`` are the field's own arrays; ``obstacle_sq``, ``skeleton`` and ``skeleton_sq``
        are read-only views of the builder's arrays (the directions pipeline never reads them; copying them cost
        ~0.2 ms a step), valid until the next :meth:`build`: copy them to keep them."""
        if not self._config.weighted:
            return build_speed_field(snapshot, frontiers, self._config)
        t0 = time.perf_counter()
        trav_full = traversable_mask(snapshot, frontiers)
        window = crop_window(snapshot.grid, trav_full | snapshot.obstacle)
        kept = self._kept
        area = None if kept is None else kept.placed(snapshot.grid, window)
        if kept is None or area is None:
            m = CAPACITY_MARGIN
            area = _clipped(snapshot.grid, window.r0 - m, window.c0 - m, window.r1 + m, window.c1 + m)
            self._kept = None  # the old arrays go before the new ones are made
            kept = self._kept = _KeptField(area, snapshot, trav_full, self._config)
        else:
            kept.update(area, snapshot, trav_full, self._config)
        field = kept.crop(window)
        field.timings_ms["distance_transforms"] = elapsed_ms(t0) - field.timings_ms["skeleton"]
        return field


def _area_inputs(
    area: Window, snapshot: MapSnapshot, trav_full: NDArray[np.bool_]
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """The traversable, skeleton-region and obstacle cells of ``area``."""
    rs, cs = area.slices
    trav = np.ascontiguousarray(trav_full[rs, cs])
    return trav, trav & snapshot.navigable[rs, cs], np.ascontiguousarray(snapshot.obstacle[rs, cs])


class _KeptField:
    """The arrays of :class:`SpeedFieldBuilder` on its capacity window ``area``, first computed in full."""

    def __init__(
        self, area: Window, snapshot: MapSnapshot, trav_full: NDArray[np.bool_], config: SpeedFieldConfig
    ) -> None:
        self.area = area
        self.traversable, self.region, obstacle = _area_inputs(area, snapshot, trav_full)
        self.obstacles = o = IncrementalTransform(obstacle, features=True)
        t1 = time.perf_counter()
        args = (config.skeleton_min_separation, config.skeleton_min_angle_ratio)
        self.skeleton = medial_skeleton(self.region, o.sq, o.frow, o.fcol, *args)
        self.skeleton_ms = elapsed_ms(t1)
        self.skeleton_edt = IncrementalTransform(self.skeleton, features=False)
        self.speed = weighted_speed(self.traversable, o.sq, self.skeleton_edt.sq, config, area.grid.resolution)

    def placed(self, grid: GridSpec, window: Window) -> Window | None:
        """The kept area in the cells of ``grid`` (the same world cells) if it holds ``window``, else None."""
        kept = self.area.grid
        if grid.resolution != kept.resolution:
            return None
        offsets = [(a - b) / grid.resolution for a, b in zip(kept.origin, grid.origin, strict=True)]
        c0, r0 = (round(v) for v in offsets)
        if any(abs(v - round(v)) > 1e-6 for v in offsets):
            return None
        r1, c1 = r0 + kept.shape[0], c0 + kept.shape[1]
        inside = 0 <= r0 <= window.r0 and window.r1 <= r1 <= grid.shape[0]
        if not (inside and 0 <= c0 <= window.c0 and window.c1 <= c1 <= grid.shape[1]):
            return None
        return Window(r0, c0, r1, c1, kept)

    def update(
        self, area: Window, snapshot: MapSnapshot, trav_full: NDArray[np.bool_], config: SpeedFieldConfig
    ) -> None:
        """Bring the kept arrays to this map, the kept area being ``area`` of its grid (see :meth:`placed`)."""
        self.area = area
        trav, region, obstacle = _area_inputs(area, snapshot, trav_full)
        obstacle_rows = self.obstacles.update(obstacle)
        t1 = time.perf_counter()
        skeleton_rows = obstacle_rows | changed_rows(region, self.region)
        skeleton_rows[1:] |= skeleton_rows[:-1].copy()  # a cell's marks also depend on the rows above and below
        skeleton_rows[:-1] |= skeleton_rows[1:].copy()
        o = self.obstacles
        args = (config.skeleton_min_separation, config.skeleton_min_angle_ratio)
        _medial_axis_rows(region, o.sq, o.frow, o.fcol, *args, skeleton_rows, self.skeleton)
        self.skeleton_ms = elapsed_ms(t1)
        speed_rows = obstacle_rows | self.skeleton_edt.update(self.skeleton) | changed_rows(trav, self.traversable)
        obs, vor = _speed_tables(config, area.grid.resolution)
        _speed_rows(trav, o.sq, self.skeleton_edt.sq, obs, vor, speed_rows, self.speed)

    def crop(self, window: Window) -> SpeedField:
        """The speed field of ``window`` (inside the kept area): copies of the kept speed and traversable cells, and
        read-only views of the kept distances and skeleton (see :meth:`SpeedFieldBuilder.build`)."""
        a = self.area
        rs, cs = slice(window.r0 - a.r0, window.r1 - a.r0), slice(window.c0 - a.c0, window.c1 - a.c0)
        return SpeedField(
            window,
            self.traversable[rs, cs].copy(),
            _read_only(self.obstacles.sq[rs, cs]),
            _read_only(self.skeleton[rs, cs]),
            _read_only(self.skeleton_edt.sq[rs, cs]),
            self.speed[rs, cs].copy(),
            {"distance_transforms": 0.0, "skeleton": self.skeleton_ms},
        )


def _read_only(view: NDArray[ScalarT]) -> NDArray[ScalarT]:
    view.flags.writeable = False
    return view
