"""Buildings of several storeys: floor plans stacked on slabs and joined by staircases (docs/floors.md).

A :class:`Building` is a list of :class:`Storey` -- each a one-floor :class:`~drivenav.envs.embedded.scene.Scene`
(walls, rooms, objects; object elevations above that storey's floor) at an elevation above the ground floor -- and
the :class:`Staircase` s between them. Every storey's plan lies on the same grid. Storey ``j`` stands on a slab of
:attr:`Building.slab` metres whose top is its floor; its ceiling is the next slab's underside (the top storey's at
its plan's ``ceiling_height``).

A staircase rises from storey ``lower`` to ``lower + 1`` in straight :class:`Flight` s, with flat
:class:`Landing` s between them. A flight of ``n`` risers has ``n - 1`` treads; its top riser lands on the next
landing or on the upper floor. Flights and landings are axis-aligned rectangles (headings 0, 90, 180 or 270
degrees). The stairs are drawn as solid steps from the lower floor up to each tread (boxes, so a depth image of
a staircase is its real geometry); for motion and distances they are a ramp from the bottom of each flight to its
top, as habitat-sim's navmesh makes of stairs (a slope the agent walks up with MOVE_FORWARD). Above a staircase the
upper storey's slab is open (the stairwell); a railing stands on the upper floor along the stairwell's edges,
except at the top of the last flight, where the stairs arrive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.grid import GridSpec

SLAB_THICKNESS = 0.2  # metres between a storey's ceiling and the floor above
RAILING_HEIGHT = 0.9  # metres above the upper floor (guard height of residential codes, 0.9-1.07 m)
RAILING_THICKNESS = 0.05  # metres
HEADINGS = (0, 90, 180, 270)  # the directions of ascent a flight may have, degrees counter-clockwise from +x

Rect = tuple[float, float, float, float]
"""An axis-aligned rectangle ``(x0, y0, x1, y1)`` in world metres, ``x0 < x1``, ``y0 < y1``."""


@dataclass(frozen=True)
class Box3:
    """An axis-aligned box of the building's structure (a step, a landing, a railing): its plan rectangle and the
    heights of its bottom and top above the ground floor."""

    rect: Rect
    bottom: float
    top: float
    railing: bool = False


@dataclass(frozen=True)
class Flight:
    """A straight flight: ``risers`` risers of ``riser`` metres and ``risers - 1`` treads of ``going`` metres,
    ``width`` metres wide. ``foot`` is the world point at the middle of its bottom edge (the foot of the first
    riser), ``heading`` the direction of ascent in degrees (one of :data:`HEADINGS`) and ``base`` the height of its
    bottom above the ground floor."""

    foot: tuple[float, float]
    heading: int
    width: float
    risers: int
    riser: float
    going: float
    base: float

    @property
    def run(self) -> float:
        """Horizontal length (m)."""
        return (self.risers - 1) * self.going

    @property
    def rise(self) -> float:
        """Height climbed (m)."""
        return self.risers * self.riser

    @property
    def top(self) -> float:
        """Height of its top (the next landing or floor) above the ground floor."""
        return self.base + self.rise

    @property
    def slope(self) -> float:
        """Gradient of its ramp (rise over run)."""
        return self.rise / self.run

    @property
    def axis(self) -> tuple[float, float]:
        """Unit vector of ascent."""
        angle = math.radians(self.heading)
        return float(round(math.cos(angle))), float(round(math.sin(angle)))

    def rect(self, start: float = 0.0, end: float | None = None) -> Rect:
        """The plan rectangle between ``start`` and ``end`` metres along the run (the whole flight by default)."""
        end = self.run if end is None else end
        (fx, fy), (ux, uy), half = self.foot, self.axis, self.width / 2.0
        xs = (
            fx + ux * start - uy * half,
            fx + ux * start + uy * half,
            fx + ux * end - uy * half,
            fx + ux * end + uy * half,
        )
        ys = (
            fy + uy * start + ux * half,
            fy + uy * start - ux * half,
            fy + uy * end + ux * half,
            fy + uy * end - ux * half,
        )
        return (min(xs), min(ys), max(xs), max(ys))

    def along(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distance of world points along the run from the foot."""
        ux, uy = self.axis
        along: NDArray[np.float64] = (x - self.foot[0]) * ux + (y - self.foot[1]) * uy
        return along

    def ramp(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """The walking surface's height at world points over the flight: from ``base`` at the foot to ``top`` at
        the far end, linearly (the navmesh's slope over the steps)."""
        heights: NDArray[np.float64] = self.base + self.rise * np.clip(self.along(x, y) / self.run, 0.0, 1.0)
        return heights

    def top_edge(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The end points of its top edge, where it arrives."""
        x0, y0, x1, y1 = self.rect(self.run, self.run)
        return (x0, y0), (x1, y1)

    def steps(self, floor: float) -> list[Box3]:
        """The solid steps, each from ``floor`` up to its tread."""
        return [
            Box3(self.rect((i - 1) * self.going, i * self.going), floor, self.base + i * self.riser)
            for i in range(1, self.risers)
        ]


@dataclass(frozen=True)
class Landing:
    """A flat platform between two flights: its plan rectangle and its height above the ground floor."""

    rect: Rect
    height: float


@dataclass(frozen=True)
class Staircase:
    """Stairs from storey ``lower`` to storey ``lower + 1``: flights in the order they are climbed, with the
    landings between them."""

    lower: int
    flights: tuple[Flight, ...]
    landings: tuple[Landing, ...] = ()

    def rects(self) -> list[Rect]:
        """The plan rectangles of its flights and landings (its footprint, and the stairwell above it)."""
        return [f.rect() for f in self.flights] + [landing.rect for landing in self.landings]

    def boxes(self, floor: float) -> list[Box3]:
        """Its solid steps and landings, from the lower storey's ``floor`` up."""
        steps = [box for flight in self.flights for box in flight.steps(floor)]
        return steps + [Box3(landing.rect, floor, landing.height) for landing in self.landings]

    def surface(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """The walking surface's height at world points (NaN off its footprint)."""
        heights = np.full(np.shape(x), np.nan)
        for landing in self.landings:
            heights[_inside(landing.rect, x, y)] = landing.height
        for flight in self.flights:
            inside = _inside(flight.rect(), x, y)
            heights[inside] = flight.ramp(x[inside], y[inside])
        return heights

    def ends(self, depth: float) -> tuple[Rect, Rect]:
        """The floor ``depth`` metres deep, the stairs' width across, before the first riser (on the lower storey)
        and beyond the last flight's top edge (on the upper one): where their users step on and off."""
        first, last = self.flights[0], self.flights[-1]
        return first.rect(-depth, 0.0), last.rect(last.run, last.run + depth)

    def slopes(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """The surface's gradient at world points (0 on landings and off the footprint)."""
        slopes = np.zeros(np.shape(x))
        for flight in self.flights:
            slopes[_inside(flight.rect(), x, y)] = flight.slope
        return slopes


def _inside(rect: Rect, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.bool_]:
    x0, y0, x1, y1 = rect
    inside: NDArray[np.bool_] = (x >= x0) & (x < x1) & (y >= y0) & (y < y1)
    return inside


def rect_cells(grid: GridSpec, rect: Rect) -> NDArray[np.bool_]:
    """The cells whose centre lies in ``rect`` (half-open, so two rectangles that share an edge share no cell)."""
    gx, gy = grid.cell_centers()
    return _inside(rect, gx, gy)


@dataclass(frozen=True)
class Storey:
    """One floor of a building: its plan (walls, rooms, objects above its floor) and its floor's height above the
    ground floor (metres)."""

    plan: Scene
    elevation: float


@dataclass(frozen=True)
class Building:
    """Storeys from the ground floor up (elevations increasing) on one grid, and the staircases between them."""

    scene_id: str
    storeys: tuple[Storey, ...]
    stairs: tuple[Staircase, ...] = ()
    source: str = ""
    slab: float = SLAB_THICKNESS

    def __post_init__(self) -> None:
        if not self.storeys:
            raise ValueError(f"{self.scene_id}: a building has at least one storey")
        grid = self.storeys[0].plan.grid
        if any(s.plan.grid != grid for s in self.storeys):
            raise ValueError(f"{self.scene_id}: every storey's plan must lie on one grid")

    @property
    def grid(self) -> GridSpec:
        return self.storeys[0].plan.grid

    @property
    def elevations(self) -> tuple[float, ...]:
        return tuple(s.elevation for s in self.storeys)

    def ceiling(self, j: int) -> float:
        """Height of storey ``j``'s ceiling above the ground floor: the next slab's underside, or the top storey's
        own ceiling height."""
        if j + 1 < len(self.storeys):
            return self.storeys[j + 1].elevation - self.slab
        return self.storeys[j].elevation + self.storeys[j].plan.ceiling_height

    def objects(self) -> list[tuple[int, ObjectInstance]]:
        """Every object with the index of its storey."""
        return [(j, obj) for j, storey in enumerate(self.storeys) for obj in storey.plan.objects]

    def storey_of(self, instance_id: int) -> int:
        """The storey holding an object (KeyError if none)."""
        for j, obj in self.objects():
            if obj.instance_id == instance_id:
                return j
        raise KeyError(instance_id)

    def storey_at(self, height: float) -> int:
        """The storey whose floor lies nearest below ``height`` + half a slab (the floor a point of that height
        stands on, or the one whose air it is in)."""
        below = [j for j, z in enumerate(self.elevations) if z <= height + self.slab / 2.0]
        return below[-1] if below else 0

    @cached_property
    def stair_cells(self) -> tuple[NDArray[np.bool_], ...]:
        """Per storey: the cells of the staircases that rise from it."""
        cells = [np.zeros(self.grid.shape, dtype=bool) for _ in self.storeys]
        for stair in self.stairs:
            for rect in stair.rects():
                cells[stair.lower] |= rect_cells(self.grid, rect)
        return tuple(cells)

    @cached_property
    def holes(self) -> tuple[NDArray[np.bool_], ...]:
        """Per storey: the cells where its slab is open (the stairwells of the staircases arriving on it)."""
        return (np.zeros(self.grid.shape, dtype=bool), *self.stair_cells[:-1])

    @cached_property
    def railings(self) -> tuple[tuple[Box3, ...], ...]:
        """Per storey: the railings along its stairwells' edges, on free floor, except where the stairs arrive."""
        per_storey: list[list[Box3]] = [[] for _ in self.storeys]
        for stair in self.stairs:
            upper = stair.lower + 1
            if upper < len(self.storeys):
                per_storey[upper].extend(_railings(self, stair, upper))
        return tuple(tuple(boxes) for boxes in per_storey)

    @cached_property
    def structure_boxes(self) -> tuple[Box3, ...]:
        """Every step, landing and railing of the building (what the renderer draws besides walls and objects)."""
        boxes = [box for stair in self.stairs for box in stair.boxes(self.storeys[stair.lower].elevation)]
        return tuple(boxes) + tuple(box for railings in self.railings for box in railings)


def _railings(building: Building, stair: Staircase, upper: int) -> list[Box3]:
    """The railings of ``stair``'s stairwell on storey ``upper``: along every edge of its rectangles that borders
    free floor of that storey (not another part of the stairwell), except the last flight's top edge."""
    grid, plan = building.grid, building.storeys[upper].plan
    floor = (plan.structure == Material.FREE) & ~building.holes[upper]
    exit_edge = stair.flights[-1].top_edge()
    elevation = building.storeys[upper].elevation
    boxes: list[Box3] = []
    for rect in stair.rects():
        for (a, b), outward in _edges(rect):
            if {a, b} == set(exit_edge):
                continue
            for lo, hi in _runs_beside(grid, floor, a, b, outward):
                boxes.append(Box3(_rail_rect(lo, hi, outward), elevation, elevation + RAILING_HEIGHT, railing=True))
    return boxes


Point = tuple[float, float]


def _edges(rect: Rect) -> list[tuple[tuple[Point, Point], tuple[int, int]]]:
    """The four edges of a rectangle (end points in increasing order) with their outward normals."""
    x0, y0, x1, y1 = rect
    return [
        (((x0, y0), (x1, y0)), (0, -1)),
        (((x0, y1), (x1, y1)), (0, 1)),
        (((x0, y0), (x0, y1)), (-1, 0)),
        (((x1, y0), (x1, y1)), (1, 0)),
    ]


def _runs_beside(
    grid: GridSpec, floor: NDArray[np.bool_], a: Point, b: Point, outward: tuple[int, int]
) -> list[tuple[Point, Point]]:
    """The stretches of the edge ``a``-``b`` whose cells just outside (along ``outward``) are ``floor``."""
    res = grid.resolution
    horizontal = outward[0] == 0
    length = (b[0] - a[0]) if horizontal else (b[1] - a[1])
    n = max(1, round(length / res))
    runs: list[tuple[Point, Point]] = []
    start: int | None = None
    for k in range(n + 1):
        ok = False
        if k < n:
            t = (k + 0.5) * length / n
            px = a[0] + (t if horizontal else 0.0) + outward[0] * res / 2.0
            py = a[1] + (0.0 if horizontal else t) + outward[1] * res / 2.0
            row, col = grid.cell_at(px, py)
            ok = 0 <= row < floor.shape[0] and 0 <= col < floor.shape[1] and bool(floor[row, col])
        if ok and start is None:
            start = k
        elif not ok and start is not None:
            lo, hi = start * length / n, k * length / n
            runs.append(
                ((a[0] + lo, a[1]), (a[0] + hi, a[1])) if horizontal else ((a[0], a[1] + lo), (a[0], a[1] + hi))
            )
            start = None
    return runs


def _rail_rect(lo: Point, hi: Point, outward: tuple[int, int]) -> Rect:
    """A railing's plan rectangle just outside the stairwell edge ``lo``-``hi``."""
    t = RAILING_THICKNESS
    xs = (lo[0], hi[0], lo[0] + outward[0] * t, hi[0] + outward[0] * t)
    ys = (lo[1], hi[1], lo[1] + outward[1] * t, hi[1] + outward[1] * t)
    return (min(xs), min(ys), max(xs), max(ys))


def storeys_of(world: Scene | Building) -> tuple[Storey, ...]:
    """The storeys of a scene: a one-floor scene is one storey at height 0."""
    return world.storeys if isinstance(world, Building) else (Storey(world, 0.0),)


def floor_plan(world: Scene | Building, height: float) -> Scene:
    """The plan of the floor a point of ``height`` stands on (a one-floor scene's own)."""
    return world.storeys[world.storey_at(height)].plan if isinstance(world, Building) else world


def stair_ends(building: Building, storey: int, depth: float) -> NDArray[np.bool_]:
    """The cells of ``storey``'s floor at the ends of its stairs (:meth:`Staircase.ends`): before the first riser of
    those rising from it and beyond the top of those arriving on it."""
    cells = np.zeros(building.grid.shape, dtype=bool)
    for stair in building.stairs:
        approach, arrival = stair.ends(depth)
        if stair.lower == storey:
            cells |= rect_cells(building.grid, approach)
        if stair.lower + 1 == storey:
            cells |= rect_cells(building.grid, arrival)
    return cells
