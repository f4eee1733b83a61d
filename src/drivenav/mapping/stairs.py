"""Stairs in the depth frames (docs/floors.md, "The body's floors"): where the floor rises in climbable steps and
where it drops away.

Two layers beside a floor's obstacle map, filled from every depth frame taken on that floor (:func:`project_relief`):

- the **relief**: per cell, the highest upward-facing point seen there up to :attr:`StairTuning.max_height` above
  the floor (the floor's own points included; a wall's face is left out, its highest point in view depends on the
  view), so that a flight is a run of treads rising in steps;
- the **drops**: cells where a ray looking down should have met the floor within the depth range and did not -- it
  went on, farther than the floor plane by more than :attr:`StairTuning.drop`, or out of range: the floor is missing
  there (a stairwell seen from above; a level camera sees no tread of a descending flight, docs/floors.md). Drops are
  obstacles of the floor's map, so no path runs into a stairwell.

A one-floor world has neither a climbable run of steps rising half a metre nor a missing floor, so these layers find
no stairs there and its maps are unchanged.

Candidates (:func:`find_stairs`), at a floor decision:

- **up**: cells reached from the floor by short steps of at most :attr:`StairTuning.climb` (habitat-sim's navmesh
  climb) through raised cells, in a connected run; in it, the cells on one plane of a flight's slope rising from its
  first steps, at least :attr:`StairTuning.min_rise` high in three treads (a staircase, not a low object: a box
  lower than the climb is no flight; the walls and railings the run also reaches lie off that plane). The direction
  of ascent is that plane's gradient; its entry the floor before its lowest cells;
- **down**: a connected region of drops at least :attr:`StairTuning.min_drop_area` large whose edge toward free
  floor is open (not walled or railed) over at least :attr:`StairTuning.min_opening`: where stairs leave the floor.
  The direction of descent runs across that opening into the region.

Suspected ways down (:func:`find_railings`, used only with ``agent.floors.railings``): a level camera at 0.88 m sees
no floor past a 0.9 m railing, so a stairwell seen from beside is a thin line of obstacles whose highest point seen is
about the camera's height, with unseen floor behind it. Such a line at least :attr:`StairTuning.min_railing` long
suggests the stairwell's open edge beyond one of its ends, where the stairs arrive: a place to go and look from, not
a way (kitchen counters are as high and give such lines too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.grid import GridSpec
from drivenav.jit import jit
from drivenav.mapping.kernels import stamp
from drivenav.mapping.types import MapSnapshot
from drivenav.ranges import LENGTH, POSITIVE_LENGTH, check_ranges

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Mask = NDArray[np.bool_]
NO_POINT = -np.inf  # the relief of a cell no point has fallen in


@dataclass(frozen=True)
class StairTuning:
    """How stairs are read from depth (module docstring; metres and square metres).

    ``climb`` 0.2: habitat-sim's navmesh climb, the largest step between treads; ``min_rise`` 0.5: a climbable run
    this high is a staircase (three risers of real stairs; no box lower than the climb can be one);
    ``drop`` 0.2: a ray reaching this much beyond the floor plane found no floor; ``max_height`` 2.5: points higher
    above the floor are out of any flight's first storey-half and left out; ``min_drop_area`` 0.25 and
    ``min_opening`` 0.5: a stairwell's drop region and its open edge (a flight is at least 0.6 m wide).
    Railings (:func:`find_railings`): ``railing_low`` 0.8 and ``railing_high`` 0.95, the highest point seen on a
    railing's cells (its face up to the camera's 0.88 m: a 0.9 m railing's top is not seen from below it);
    ``min_railing`` 2.0, the least length of a railing line (a flight's run is 3 m or more; a kitchen counter is up
    to 3 m);
    ``railing_beyond`` 0.6 and ``railing_across`` 0.45, where the agent looks from: that far beyond an end of the
    line and toward its unseen side (the middle of a flight 0.75-1.0 m wide, in the strip of floor where it arrives).
    """

    climb: float = 0.2
    min_rise: float = 0.5
    drop: float = 0.2
    max_height: float = 2.5
    min_drop_area: float = 0.25
    min_opening: float = 0.5
    railing_low: float = 0.8
    railing_high: float = 0.95
    min_railing: float = 2.0
    railing_beyond: float = 0.6
    railing_across: float = 0.45

    def __post_init__(self) -> None:
        check_ranges(
            self,
            {
                "climb": POSITIVE_LENGTH,
                "min_rise": POSITIVE_LENGTH,
                "drop": POSITIVE_LENGTH,
                "max_height": POSITIVE_LENGTH,
                "min_drop_area": LENGTH,
                "min_opening": LENGTH,
                "railing_low": LENGTH,
                "railing_high": POSITIVE_LENGTH,
                "min_railing": LENGTH,
                "railing_beyond": LENGTH,
                "railing_across": LENGTH,
            },
        )


@dataclass(frozen=True)
class Relief:
    """A floor's stair layers (module docstring), on its map's grid."""

    grid: GridSpec
    top: NDArray[np.float32]
    drops: Mask


@dataclass(frozen=True)
class StairCandidate:
    """A way off the floor: the point on the floor to set out from (episode frame), the heading to drive (radians,
    counter-clockwise), and whether the stairs go up; ``seen`` False: a way only suspected (:func:`find_railings`),
    whose entry is where to look from and its heading where to look."""

    entry: tuple[float, float]
    heading: float
    up: bool
    seen: bool = True


@jit(
    "i8(f4[:, ::1], i8[::1], i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f4[:, ::1], b1[:, ::1], b1[:, ::1],"
    " b1[:, ::1], i8[:, ::1])"
)
def project_relief(
    depth: NDArray[np.float32],
    rows: I64,
    cols: I64,
    camera: F64,
    band: F64,
    pose: F64,
    grid: F64,
    top: NDArray[np.float32],
    drops: Mask,
    obstacle: Mask,
    inflated: Mask,
    disk: I64,
) -> int:
    """Raise ``top`` to the heights of the subsampled depth pixels' points that face up and mark ``drops`` where a
    downward ray passed the floor plane (module docstring). A point faces up -- a tread, a floor, the top of a box or
    a railing -- when the surface toward the sampled row above it in the image rises less than it recedes (flatter
    than 45 degrees) or nothing is seen there within range; a wall's or a riser's points lie straight above each other
    and do not (the top row of a frame, with nothing above it, neither: a wall's highest point in view is where the
    view ends, not where the wall does); a new drop is an obstacle too, stamped with ``disk`` into
    ``inflated``. ``camera`` = (fx, fy, cx, cy, camera height), ``band`` = (min depth, max depth, clip epsilon, drop,
    max height), ``pose`` = (x, y, yaw), ``grid`` = (origin x, origin y, resolution). Returns the new drop cells."""
    fx, fy, cx, cy, cam_h = camera[0], camera[1], camera[2], camera[3], camera[4]
    min_d, max_d, eps, drop, max_h = band[0], band[1], band[2], band[3], band[4]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ox, oy, res = grid[0], grid[1], grid[2]
    n_rows, n_cols = top.shape
    added = 0
    for k in range(cols.shape[0]):
        kx = (cx - cols[k]) / fx
        stretch = math.sqrt(1.0 + kx * kx)  # horizontal distance per metre of depth in this column
        above_z, above_h = -1.0, 0.0  # the point of the sampled row above (-1: none, or nothing seen there)
        for v in rows:
            z = depth[v, cols[k]]
            ky = (cy - v) / fy
            if not (math.isfinite(z) and z > min_d + eps):
                above_z = -1.0
                continue
            if ky < 0.0:
                floor_d = cam_h / -ky
                if floor_d < max_d - eps and (z >= max_d - eps or z > floor_d + drop / -ky):
                    i = math.floor((pose[1] + s * floor_d + c * floor_d * kx - oy) / res)
                    j = math.floor((pose[0] + c * floor_d - s * floor_d * kx - ox) / res)
                    if 0 <= i < n_rows and 0 <= j < n_cols and not drops[i, j]:
                        drops[i, j] = True
                        obstacle[i, j] = True
                        stamp(inflated, i, j, disk)
                        added += 1
            h = cam_h + ky * z
            open_above = above_z >= max_d - eps or (above_z > 0.0 and (above_z - z) * stretch > above_h - h)
            above_z, above_h = z, h
            if z >= max_d - eps or h > max_h or not open_above:
                continue
            i = math.floor((pose[1] + s * z + c * z * kx - oy) / res)
            j = math.floor((pose[0] + c * z - s * z * kx - ox) / res)
            if 0 <= i < n_rows and 0 <= j < n_cols and h > top[i, j]:
                top[i, j] = h
    return added


def find_stairs(relief: Relief, snapshot: MapSnapshot, tuning: StairTuning) -> list[StairCandidate]:
    """The ways up and down a floor's map shows (module docstring): flights rising from its floor, stairwells whose
    edge toward its floor is open. ``snapshot`` gives the map's free floor (explored cells without an obstacle: the
    floor just before a flight is too close under the camera to be seen as points) and its obstacles (drops
    included)."""
    free = snapshot.explored & ~snapshot.obstacle & ~relief.drops
    return [*_flights_up(relief, free, tuning), *_flights_down(relief, snapshot, tuning)]


def _flights_up(relief: Relief, free: Mask, tuning: StairTuning) -> list[StairCandidate]:
    """Runs of raised cells climbed from the floor (:func:`_climbed`) holding a flight (:func:`_ascent`)."""
    top = relief.top
    raised = np.isfinite(top) & (top >= tuning.climb / 2.0) & ~relief.drops
    near_floor = ndimage.binary_dilation(free, iterations=GAP_CELLS)
    first = raised & near_floor & (top <= tuning.climb)
    run = _climbed(first, raised, top, tuning.climb)
    labels, count = ndimage.label(ndimage.binary_dilation(run, iterations=GAP_CELLS), structure=np.ones((3, 3), bool))
    found: list[StairCandidate] = []
    for k in range(1, count + 1):
        cells = np.argwhere(run & (labels == k))
        heights = top[cells[:, 0], cells[:, 1]].astype(np.float64)
        if heights.max() < tuning.min_rise:
            continue
        candidate = _ascent(relief.grid, cells, heights, tuning)
        if candidate is not None:
            found.append(candidate)
    return found


@jit("b1[:, ::1](b1[:, ::1], b1[:, ::1], f4[:, ::1], f8, i8)")
def _climb_kernel(first: Mask, raised: Mask, top: NDArray[np.float32], climb: float, gap: int) -> Mask:
    """Breadth-first from ``first`` over ``raised`` cells: a step to a cell at most ``gap`` cells away (treads far off
    are seen in sparse points) rising or falling at most ``climb`` plus a flight's rise over that distance."""
    rows, cols = raised.shape
    reached: Mask = first.copy()
    queue = np.empty(rows * cols, np.int64)
    n = 0
    for r in range(rows):
        for c in range(cols):
            if first[r, c]:
                queue[n] = r * cols + c
                n += 1
    head = 0
    while head < n:
        r, c = queue[head] // cols, queue[head] % cols
        head += 1
        for dr in range(-gap, gap + 1):
            for dc in range(-gap, gap + 1):
                rr, cc = r + dr, c + dc
                if rr < 0 or rr >= rows or cc < 0 or cc >= cols or reached[rr, cc] or not raised[rr, cc]:
                    continue
                if abs(top[rr, cc] - top[r, c]) <= climb + 0.05 * max(abs(dr), abs(dc)):
                    reached[rr, cc] = True
                    queue[n] = rr * cols + cc
                    n += 1
    return reached


def _climbed(first: Mask, raised: Mask, top: NDArray[np.float32], climb: float) -> Mask:
    """The raised cells reached from the ``first`` steps (raised cells beside the floor, one climb up) by steps the
    agent could climb (:func:`_climb_kernel`): a flight's treads, not the wall beside it."""
    reached = _climb_kernel(
        np.ascontiguousarray(first), np.ascontiguousarray(raised), np.ascontiguousarray(top), float(climb), GAP_CELLS
    )
    return np.asarray(reached, dtype=np.bool_)


GAP_CELLS = 2  # cells of unseen floor bridged between points of one run
MIN_TREADS = 3  # distinct heights, a riser apart, a run of stairs shows at least
SLOPES = np.arange(0.35, 1.05 + 1e-9, 0.05)  # rise over run of a flight: 19-46 degrees (the navmesh walks 45)
BEARINGS = np.radians(np.arange(0.0, 360.0, 2.0))  # directions of ascent tried
MIN_WIDTH = 0.4  # metres across the ascent the cells on a flight's plane span (a flight is 0.6 m wide or more; a
# railing or a wall's edge seen rising along the flight is a line)
ON_PLANE = 0.1  # metres: a tread lies within half a riser of the plane through the flight's nosings


def _treads(heights: F64, climb: float) -> int:
    """How many distinct heights the run shows, each more than a third of a climb above the last (the treads of a
    flight; a box shows one, a box on a box two)."""
    levels = 0
    last = -np.inf
    for h in np.sort(heights):
        if h > last + climb / 3.0:
            levels += 1
            last = h
    return levels


def _ascent(grid: GridSpec, cells: I64, heights: F64, tuning: StairTuning) -> StairCandidate | None:
    """A flight in a climbed run, or None: the plane rising from the run's first steps (heights up to a climb) that
    most of its cells lie on (:func:`_flight_plane`), when the cells on it rise ``min_rise`` in :data:`MIN_TREADS`
    treads and span :data:`MIN_WIDTH` across their length (else a railing or a wall's edge). Its heading is that
    plane's bearing; its entry the floor 0.35 m before its lowest cells, against that heading. The cells a run also
    holds -- walls and railings beside the flight, seen in part -- lie off that plane and are left out."""
    xy = grid.cell_to_world(cells)
    low = heights <= tuning.climb
    if not low.any():
        return None
    heading, on = _flight_plane(xy - xy[low].mean(axis=0), heights - heights[low].mean(), tuning.climb)
    if heights[on].max() < tuning.min_rise or _treads(heights[on], tuning.climb) < MIN_TREADS:
        return None
    if _narrowest(xy[on]) < MIN_WIDTH:
        return None
    first = xy[on][heights[on] <= heights[on].min() + tuning.climb]
    foot = first.mean(axis=0) - 0.35 * np.array([math.cos(heading), math.sin(heading)])
    return StairCandidate((float(foot[0]), float(foot[1])), heading, up=True)


def _narrowest(xy: F64) -> float:
    """The points' extent along their minor principal axis."""
    centred = xy - xy.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    return float(np.ptp(centred @ axes[-1]))


def _flight_plane(offsets: F64, rises: F64, climb: float) -> tuple[float, Mask]:
    """The bearing of the plane through the run's first steps that explains its rise best, and which cells lie within
    :data:`ON_PLANE` of it: every bearing of :data:`BEARINGS` and slope of :data:`SLOPES` tried, ``offsets`` and
    ``rises`` measured from those steps. Best is the plane whose cells climb highest from the first steps without a
    gap of more than a riser (:func:`_climbed_bins`), then the one most cells lie on: a flight rises tread by tread,
    cells that happen to lie on a wrong plane scatter in height."""
    bins = np.clip(np.floor(rises / climb), 0, None).astype(np.int64)
    one_hot = np.zeros((len(rises), int(bins.max()) + 1))
    one_hot[np.arange(len(rises)), bins] = 1.0
    best: Mask = np.zeros(len(rises), dtype=np.bool_)
    best_score = (-1, -1)
    best_bearing = 0.0
    for bearing in BEARINGS:
        along = offsets @ np.array([math.cos(bearing), math.sin(bearing)])
        on = np.abs(SLOPES[:, None] * along[None, :] - rises[None, :]) <= ON_PLANE
        reached = _climbed_bins(on @ one_hot > 0.0)
        counts = on.sum(axis=1)
        k = int(np.lexsort((counts, reached))[-1])
        if (int(reached[k]), int(counts[k])) > best_score:
            best, best_score, best_bearing = on[k], (int(reached[k]), int(counts[k])), float(bearing)
    return best_bearing, best


def _climbed_bins(present: Mask) -> I64:
    """Per row of ``present`` (which height bins, a climb each, hold cells), how many bins from the first one on
    are covered with no two missing in a row."""
    gaps = ~present[:, :-1] & ~present[:, 1:]
    gaps = np.concatenate([gaps, np.ones((len(present), 1), dtype=np.bool_)], axis=1)
    covered: I64 = np.argmax(gaps, axis=1).astype(np.int64)
    return covered


def _flights_down(relief: Relief, snapshot: MapSnapshot, tuning: StairTuning) -> list[StairCandidate]:
    """Drop regions (their unseen gaps closed) with an opening toward the floor: navigable cells a short reach from the
    region, the reach not passing walls or railings, nor cells never seen (a railing not yet seen is no gap). The way
    down sets out from the opening's middle, across it (:func:`_into`)."""
    grid = relief.grid
    walls = snapshot.obstacle & ~relief.drops
    drops = ndimage.binary_closing(relief.drops, iterations=GAP_CELLS) & ~walls
    reach = OPENING_REACH_CELLS
    labels, count = ndimage.label(drops, structure=np.ones((3, 3), bool))
    found: list[StairCandidate] = []
    for k in range(1, count + 1):
        region = labels == k
        if region.sum() * grid.resolution**2 < tuning.min_drop_area:
            continue
        near = ndimage.binary_dilation(region, iterations=reach, mask=(snapshot.explored | drops) & ~walls)
        opening = snapshot.navigable & near
        if opening.sum() * grid.resolution**2 < tuning.min_opening * grid.resolution * 2:
            continue
        edge = grid.cell_to_world(np.argwhere(opening))
        mouth = edge.mean(axis=0)
        inside = grid.cell_to_world(np.argwhere(region)).mean(axis=0)
        heading = _into(edge - mouth, inside - mouth)
        found.append(StairCandidate((float(mouth[0]), float(mouth[1])), heading, up=False))
    return found


def _into(edge: F64, toward: F64) -> float:
    """The heading across an opening: perpendicular to its cells' major axis (``edge``, centred), on the side of
    ``toward``; straight toward it where the opening is no longer than deep."""
    _, spread, axes = np.linalg.svd(edge, full_matrices=False)
    if len(spread) < 2 or spread[0] < 1.5 * spread[1]:
        return math.atan2(toward[1], toward[0])
    normal = np.array([-axes[0, 1], axes[0, 0]])
    if normal @ toward < 0.0:
        normal = -normal
    return math.atan2(normal[1], normal[0])


OPENING_REACH_CELLS = 8  # cells from a stairwell to the floor its opening gives on: the inflation and two cells more


def find_railings(relief: Relief, snapshot: MapSnapshot, tuning: StairTuning) -> list[StairCandidate]:
    """Suspected ways down behind railings (module docstring): for each thin line of obstacle cells whose highest
    point seen lies between :attr:`StairTuning.railing_low` and :attr:`StairTuning.railing_high`, at least
    :attr:`StairTuning.min_railing` long, each end (:func:`_railing_ends`) gives the
    point :attr:`StairTuning.railing_beyond` past it and :attr:`StairTuning.railing_across` toward the line's unseen
    side, looking back along the line."""
    top = relief.top
    low = snapshot.obstacle & ~relief.drops & (top >= tuning.railing_low) & (top <= tuning.railing_high)
    thin = low & ~ndimage.binary_opening(low, structure=np.ones((3, 3), bool))  # furniture tops seen are areas
    labels, count = ndimage.label(thin, structure=np.ones((3, 3), bool))
    unseen = ~snapshot.explored & ~snapshot.obstacle
    found: list[StairCandidate] = []
    for k in range(1, count + 1):
        xy = relief.grid.cell_to_world(np.argwhere(labels == k))
        ends = _railing_ends(xy, unseen, relief.grid, tuning)
        clear = [end for end, crossed in ends if not _count_in(snapshot.obstacle, relief.grid, crossed)]
        found += clear or [end for end, _ in ends]
    return found


def _railing_ends(xy: F64, unseen: Mask, grid: GridSpec, tuning: StairTuning) -> list[tuple[StairCandidate, F64]]:
    """Where to look from at each end of one railing line (its cells' centres ``xy``), with the points from the
    unseen side's middle at that end out to there: its major axis ``u`` long enough; its unseen side ``n`` the one
    with more cells never seen :data:`RAILING_PROBE` away from the line's middle; each end the mean of the line's
    cells within :data:`RAILING_END` of it. An obstacle on those points is a railing or wall across the stairwell at
    that end (:func:`find_railings` then keeps the other end; both where both are crossed, or neither: the railing
    across is not always seen, and looking from the wrong end costs a few steps)."""
    if len(xy) * grid.resolution < tuning.min_railing:  # too few cells to span the length
        return []
    centre = xy.mean(axis=0)
    _, _, axes = np.linalg.svd(xy - centre, full_matrices=False)
    u, n = axes[0], axes[1]
    along = (xy - centre) @ u
    if np.ptp(along) < tuning.min_railing:
        return []
    middle = xy[np.abs(along) <= np.ptp(along) / 4.0]
    sides = [int(_count_in(unseen, grid, middle + sign * RAILING_PROBE * n)) for sign in (1.0, -1.0)]
    if max(sides) == 0:
        return []
    side = n if sides[0] >= sides[1] else -n
    ends: list[tuple[StairCandidate, F64]] = []
    for sign, extreme in ((1.0, along.max()), (-1.0, along.min())):
        near_end = np.abs(along - extreme) <= RAILING_END
        outward = sign * u
        inside = xy[near_end].mean(axis=0) + tuning.railing_across * side
        look_from = inside + tuning.railing_beyond * outward
        crossed = inside + np.linspace(0.0, tuning.railing_beyond, 13)[:, None] * outward
        heading = math.atan2(-outward[1], -outward[0])
        way = StairCandidate((float(look_from[0]), float(look_from[1])), heading, up=False, seen=False)
        ends.append((way, crossed))
    return ends


def _count_in(mask: Mask, grid: GridSpec, points: F64) -> int:
    """How many of ``points`` fall on true cells of ``mask`` (points off the grid count none)."""
    cells = grid.world_to_cell(points)
    cells = cells[grid.contains(cells)]
    return int(mask[cells[:, 0], cells[:, 1]].sum())


RAILING_PROBE = 0.3  # metres from a railing line at which its sides are told apart (seen floor, unseen stairwell)
RAILING_END = 0.25  # metres from a line's extreme along it within which its cells make its end
