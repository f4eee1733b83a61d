"""Procedural houses: a seeded floor plan with named rooms, doors, corridors with T-junctions, and objects.

Layout. Houses of 1-3 rooms are a rectangle split into rooms (binary space partition) joined by doors. Larger
houses have a corridor *spine* with a living room at one end, optionally a room capping the other end, and
1-3 *branch* corridors leaving the spine at T-junctions (the structure DRIVE-Nav's directional reasoning acts
on, Sec. IV-A). The blocks between corridors are split into rooms so that most rooms open onto a corridor;
the rest open onto a neighbour. Room types are assigned by size (the largest rooms get the types that are
usually large). The plan is mirrored and transposed at random and rasterised onto the structure grid: walls
0.10-0.15 m thick, door openings 0.8-1.1 m wide with :attr:`Material.DOOR_FRAME` jambs, and unknown space
outside. Objects come from :func:`drivenav.envs.embedded.placement.place_objects` with the same generator.

Everything is drawn from ``numpy.random.default_rng(seed)``, so a seed always gives the same house.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.placement import place_objects
from drivenav.envs.embedded.scene import Material, Room, Scene
from drivenav.errors import InputError
from drivenav.grid import GridSpec

MAX_ROOMS = 15
HALLWAY = "hallway"

_MIN_SIDE = 2.2  # metres: the shortest side a room may get from a split
MIN_BLOCK = 2.6  # metres: the narrowest block between two branches
_DOOR_WIDTH = (0.8, 1.1)
_CORRIDOR_WIDTH = (1.2, 1.8)
WALL_THICKNESS = (0.10, 0.15)
_SPLIT_END_HEIGHT = 9.0  # metres: taller rooms at the spine's ends are split in two
JAMB = 0.1  # metres of door frame on each side of an opening
OUTSIDE_MARGIN = 0.3  # metres of unknown space around the house

# Typical floor area (m^2) per room type: the largest rooms of a plan get the types that are usually largest.
_TYPICAL_AREA: dict[str, float] = {
    "living room": 25.0,
    "garage": 24.0,
    "dining room": 14.0,
    "gym": 13.0,
    "bedroom": 13.0,
    "playroom": 12.0,
    "kitchen": 12.0,
    "office": 10.0,
    "bathroom": 6.0,
    "laundry room": 5.0,
    "closet": 3.5,
}
_ESSENTIAL = ("kitchen", "bedroom", "bathroom")
# (type, weight, most rooms of that type in a house) for the rooms beyond the essential ones.
_EXTRA: tuple[tuple[str, float, int], ...] = (
    ("bedroom", 3.0, 5),
    ("bathroom", 2.0, 3),
    ("dining room", 1.5, 1),
    ("office", 1.5, 2),
    ("closet", 1.2, 3),
    ("laundry room", 1.0, 1),
    ("playroom", 0.8, 1),
    ("gym", 0.6, 1),
    ("garage", 0.5, 1),
)
_CAP_TYPES = ("bedroom", "garage", "dining room", "gym", "playroom", "office")
_COMPACT_TYPES = {1: ("living room",), 2: ("living room", "bathroom"), 3: ("living room", "bedroom", "bathroom")}
# Room-type pairs that get a second door when they are neighbours (open-plan loops).
_EXTRA_DOOR_PAIRS = (frozenset({"living room", "dining room"}), frozenset({"kitchen", "dining room"}))


@dataclass(frozen=True)
class Box:
    """An axis-aligned rectangle in metres, between wall centre lines."""

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        return self.y1 - self.y0

    @property
    def area(self) -> float:
        return self.width * self.height


# Which sides of a block border a corridor: (left, right, bottom, top).
Touch = tuple[bool, bool, bool, bool]


@dataclass
class Plan:
    """A floor plan in metres: rooms, corridors (the spine first) and the types fixed by the layout."""

    width: float
    height: float
    rooms: list[Box]
    corridors: list[Box] = field(default_factory=list)
    fixed_types: dict[int, str] = field(default_factory=dict)


@dataclass(frozen=True)
class CellBox:
    """A :class:`Box` snapped to the grid: wall centre lines at cell columns ``c0, c1`` and rows ``r0, r1``."""

    c0: int
    r0: int
    c1: int
    r1: int


@dataclass(frozen=True)
class Edge:
    """A wall shared by two boxes: ``vertical`` wall at column ``line`` (else row), over ``[lo, hi)``."""

    vertical: bool
    line: int
    lo: int
    hi: int


def generate_house(seed: int, num_rooms: int | None = None, resolution: float = 0.05) -> Scene:
    """A procedural house with rooms, doors, corridors and objects, fully determined by ``seed``.

    ``num_rooms`` counts the rooms proper (corridors, named ``"hallway"``, come on top); when ``None`` it
    is drawn from the seed in ``1..15``. The house lies in ``x, y >= 0`` (the outer walls' centre lines
    start at the world origin); the footprint is 40-400 m^2.
    """
    if num_rooms is not None and not (isinstance(num_rooms, int) and 1 <= num_rooms <= MAX_ROOMS):
        raise InputError("generate_house", "num_rooms", f"an integer in 1..{MAX_ROOMS} or None", num_rooms)
    if not 0.01 <= resolution <= 0.2:
        raise InputError("generate_house", "resolution", "metres per cell in [0.01, 0.2]", resolution)
    rng = np.random.default_rng(seed)
    drawn = int(rng.integers(1, MAX_ROOMS + 1))  # always drawn, so num_rooms=drawn gives the same house
    n = drawn if num_rooms is None else num_rooms
    plan = transform_plan(rng, _compact_plan(rng, n) if n <= 3 else _corridor_plan(rng, n))
    names = _room_types(rng, plan)
    scene = _build_scene(rng, plan, names, resolution, f"procedural/house_{seed:05d}")
    return replace(scene, objects=place_objects(scene, rng))


# --------------------------------------------------------------------------------------------- layout


def _compact_plan(rng: np.random.Generator, n: int) -> Plan:
    """1-3 rooms: a rectangle of 40-65 m^2; the first cut leaves a large living room, the next a small room."""
    area = rng.uniform(40.0, 55.0) if n <= 2 else rng.uniform(45.0, 65.0)
    aspect = rng.uniform(1.0, 1.5)
    width = math.sqrt(area * aspect)
    rooms = [Box(0.0, 0.0, width, area / width)]
    for frac in (rng.uniform(0.6, 0.72), rng.uniform(0.55, 0.65))[: n - 1]:
        rest = rooms.pop()
        rooms.extend(_cut(rest, frac, rest.width >= rest.height))
    return Plan(width, area / width, rooms)


def _branch_count(rng: np.random.Generator, n: int) -> int:
    if n == 4:
        return int(rng.random() < 0.6)
    if n <= 8:
        return 1
    if n <= 12:
        return 1 + int(rng.random() < 0.6)
    return 2 + int(rng.random() < 0.5)


def _corridor_plan(rng: np.random.Generator, n: int) -> Plan:
    """4-15 rooms: a spine with branches (T-junctions), a living room at one end, rooms along both sides.

    The rooms at the spine's ends span the house's height; in tall houses such an end is split in two at
    the spine's edge, so the end room that the spine opens into keeps a sensible shape.
    """
    spine_width = rng.uniform(*_CORRIDOR_WIDTH)
    n_branches = _branch_count(rng, n)
    end_types = ["living room"]
    if n >= 7 and rng.random() < 0.5:
        end_types.append(_CAP_TYPES[int(rng.integers(len(_CAP_TYPES)))])
    branch_side = rng.integers(0, 2, n_branches)  # 0: below the spine, 1: above it
    branch_width = rng.uniform(*_CORRIDOR_WIDTH, n_branches)
    depth = [rng.uniform(5.5, 7.5) if np.any(branch_side == s) else rng.uniform(3.2, 4.8) for s in (0, 1)]
    end_width = [rng.uniform(3.8, 5.5), rng.uniform(3.0, 4.5)][: len(end_types)]
    room_area = rng.uniform(10.0, 14.0)
    y0, y1 = depth[0], depth[0] + spine_width
    height = y1 + depth[1]
    side_rooms = n - len(end_types)
    n_blocks = n_branches + 2
    split_ends = min(len(end_types), side_rooms - n_blocks) if height > _SPLIT_END_HEIGHT else 0
    side_rooms -= split_ends

    branch_area = float(sum(w * depth[s] for w, s in zip(branch_width, branch_side, strict=True)))
    min_span = max((np.sum(branch_side == s) + 1) * MIN_BLOCK + branch_width[branch_side == s].sum() for s in (0, 1))
    span = max((side_rooms * room_area + branch_area) / (depth[0] + depth[1]), float(min_span))
    x0, x1 = end_width[0], end_width[0] + span

    plan = Plan(x1 + sum(end_width[1:]), height, [], [Box(x0, y0, x1, y1)])
    for k, (xa, xb) in enumerate(((0.0, x0), (x1, plan.width))[: len(end_types)]):
        plan.fixed_types[len(plan.rooms)] = end_types[k]
        if k < split_ends:
            cut = y0 if rng.random() < 0.5 else y1  # the part holding the spine's end [y0, y1] comes first
            near, far = (Box(xa, cut, xb, height), Box(xa, 0.0, xb, cut))
            plan.rooms.extend((near, far) if cut == y0 else (far, near))
        else:
            plan.rooms.append(Box(xa, 0.0, xb, height))
    blocks = [
        block
        for side, (ylo, yhi) in enumerate(((0.0, y0), (y1, height)))
        for block in side_blocks(rng, plan, (x0, x1, ylo, yhi), branch_width[branch_side == side], side)
    ]
    for (box, touch), k in zip(blocks, allocate_cells(side_rooms, [b.area for b, _ in blocks]), strict=True):
        plan.rooms.extend(split_box(rng, box, k, touch))
    return plan


def side_blocks(
    rng: np.random.Generator,
    plan: Plan,
    bounds: tuple[float, float, float, float],
    widths: NDArray[np.float64],
    side: int,
) -> list[tuple[Box, Touch]]:
    """Cut one side of the spine (``side`` 0 below, 1 above) into blocks by branch corridors (added to plan).

    Returns the blocks with the sides on which they touch a corridor.
    """
    x0, x1, ylo, yhi = bounds
    free = (x1 - x0) - widths.sum() - (len(widths) + 1) * MIN_BLOCK
    parts = MIN_BLOCK + free * rng.dirichlet(np.full(len(widths) + 1, 4.0))
    blocks: list[tuple[Box, Touch]] = []
    x = x0
    for j, part in enumerate(parts):
        right = x1 if j == len(widths) else x + float(part)
        blocks.append((Box(x, ylo, right, yhi), (j > 0, j < len(widths), side == 1, side == 0)))
        if j < len(widths):
            after = right + float(widths[j])
            plan.corridors.append(Box(right, ylo, after, yhi))
            x = after
    return blocks


def allocate_cells(total: int, areas: list[float]) -> list[int]:
    """Spread ``total`` rooms over blocks, at least one each, keeping the area per room as even as possible."""
    counts = [1] * len(areas)
    for _ in range(total - len(areas)):
        best = max(range(len(areas)), key=lambda b: areas[b] / counts[b])
        counts[best] += 1
    return counts


def _cut(box: Box, frac: float, vertical: bool) -> tuple[Box, Box]:
    """Cut ``box`` at ``frac`` of its width (``vertical`` cut, at constant x) or of its height."""
    if vertical:
        x = box.x0 + frac * box.width
        return Box(box.x0, box.y0, x, box.y1), Box(x, box.y0, box.x1, box.y1)
    y = box.y0 + frac * box.height
    return Box(box.x0, box.y0, box.x1, y), Box(box.x0, y, box.x1, box.y1)


def split_box(rng: np.random.Generator, box: Box, k: int, touch: Touch) -> list[Box]:
    """Guillotine-split ``box`` into ``k`` rooms, preferring cuts that leave every room on a corridor.

    A cut at constant x keeps both parts on a corridor along the bottom or top side; a cut at constant y on
    one along the left or right side. Cuts that would leave a side below ``_MIN_SIDE`` come last.
    """
    if k == 1:
        return [box]
    k_first = k // 2 if rng.random() < 0.5 else k - k // 2
    fits_v = box.width / k >= _MIN_SIDE
    fits_h = box.height / k >= _MIN_SIDE
    score_v = ((touch[2] or touch[3]) and fits_v, fits_v, box.width >= box.height)
    score_h = ((touch[0] or touch[1]) and fits_h, fits_h, box.height > box.width)
    vertical = score_v >= score_h
    first, second = _cut(box, k_first / k + rng.uniform(-0.06, 0.06), vertical)
    if vertical:
        touch_first, touch_second = (touch[0], False, touch[2], touch[3]), (False, touch[1], touch[2], touch[3])
    else:
        touch_first, touch_second = (touch[0], touch[1], touch[2], False), (touch[0], touch[1], False, touch[3])
    return split_box(rng, first, k_first, touch_first) + split_box(rng, second, k - k_first, touch_second)


Transform = tuple[bool, bool, bool]
"""A plan's mirroring in x, in y, and whether its axes are swapped."""


def draw_transform(rng: np.random.Generator) -> Transform:
    """A mirroring and axis swap drawn at random (one draw of three bits)."""
    flip_x, flip_y, swap = (bool(v) for v in rng.integers(0, 2, 3))
    return flip_x, flip_y, swap


def transform_plan(rng: np.random.Generator, plan: Plan) -> Plan:
    """Mirror the plan in x and/or y and maybe swap the axes, for variety."""
    return apply_transform(plan, draw_transform(rng))


def apply_transform(plan: Plan, transform: Transform) -> Plan:
    """The plan mirrored and swapped as ``transform`` says."""
    swap = transform[2]
    rooms = [transform_box(plan, b, transform) for b in plan.rooms]
    corridors = [transform_box(plan, b, transform) for b in plan.corridors]
    width, height = (plan.height, plan.width) if swap else (plan.width, plan.height)
    return Plan(width, height, rooms, corridors, plan.fixed_types)


def transform_box(plan: Plan, box: Box, transform: Transform) -> Box:
    """One box of ``plan`` mirrored and swapped as ``transform`` says."""
    flip_x, flip_y, swap = transform
    xa, xb = (plan.width - box.x1, plan.width - box.x0) if flip_x else (box.x0, box.x1)
    ya, yb = (plan.height - box.y1, plan.height - box.y0) if flip_y else (box.y0, box.y1)
    return Box(ya, xa, yb, xb) if swap else Box(xa, ya, xb, yb)


def _room_types(rng: np.random.Generator, plan: Plan) -> list[str]:
    """Room type per room: fixed ones kept, the rest matched by size to a drawn list of types."""
    free = [k for k in range(len(plan.rooms)) if k not in plan.fixed_types]
    if not plan.corridors:
        wanted = list(_COMPACT_TYPES[len(plan.rooms)])
    else:
        wanted = list(_ESSENTIAL[: len(free)])
        while len(wanted) < len(free):
            taken = wanted + list(plan.fixed_types.values())
            allowed = [(t, w) for t, w, cap in _EXTRA if taken.count(t) < cap]
            weights = np.array([w for _, w in allowed])
            wanted.append(allowed[int(rng.choice(len(allowed), p=weights / weights.sum()))][0])
    keys = np.array([_TYPICAL_AREA[t] for t in wanted]) * rng.lognormal(0.0, 0.3, len(wanted))
    by_size = sorted(free, key=lambda k: -plan.rooms[k].area)
    names = dict(plan.fixed_types)
    for k, t in zip(by_size, (wanted[i] for i in np.argsort(-keys, kind="stable")), strict=True):
        names[k] = t
    return [names[k] for k in range(len(plan.rooms))]


# ---------------------------------------------------------------------------------------- rasterising


@dataclass(frozen=True)
class Raster:
    """Cell geometry of one house: wall thickness ``t`` (its first ``h`` cells lie before the centre line)."""

    resolution: float
    t: int
    margin: int
    jamb: int

    @property
    def h(self) -> int:
        return self.t // 2

    @property
    def min_door(self) -> int:
        """The narrowest door opening in cells (at least 0.8 m)."""
        return math.ceil(_DOOR_WIDTH[0] / self.resolution - 1e-9)

    def cell(self, metres: float) -> int:
        return self.margin + round(metres / self.resolution)

    def snap(self, box: Box) -> CellBox:
        return CellBox(self.cell(box.x0), self.cell(box.y0), self.cell(box.x1), self.cell(box.y1))

    def interior(self, lo: int, hi: int) -> tuple[int, int]:
        """Free cells between wall centre lines ``lo`` and ``hi``."""
        return lo - self.h + self.t, hi - self.h

    def paint(self, structure: NDArray[np.uint8], edge: Edge, lo: int, hi: int, material: Material) -> None:
        """Set the wall strip of ``edge`` over ``[lo, hi)`` along it to ``material``."""
        across = slice(edge.line - self.h, edge.line - self.h + self.t)
        if edge.vertical:
            structure[lo:hi, across] = material
        else:
            structure[across, lo:hi] = material


def shared_edge(a: CellBox, b: CellBox) -> Edge | None:
    """The wall two boxes share, if their sides touch over a non-empty stretch."""
    for vertical, (a_lo, a_hi, b_lo, b_hi), along in (
        (True, (a.c0, a.c1, b.c0, b.c1), (a.r0, a.r1, b.r0, b.r1)),
        (False, (a.r0, a.r1, b.r0, b.r1), (a.c0, a.c1, b.c0, b.c1)),
    ):
        line = a_hi if a_hi == b_lo else a_lo if a_lo == b_hi else None
        lo, hi = max(along[0], along[2]), min(along[1], along[3])
        if line is not None and hi > lo:
            return Edge(vertical, line, lo, hi)
    return None


@dataclass
class Floor:
    """A plan drawn on the structure grid before its doors: walls, free room and hall interiors, halls opened into
    each other; each box's cell extent and label (rooms by name, then the halls)."""

    raster: Raster
    boxes: list[CellBox]
    structure: NDArray[np.uint8]
    extents: list[list[int]]
    labels: list[str]

    def named_extents(self) -> list[tuple[str, list[int]]]:
        return list(zip(self.labels, self.extents, strict=True))

    def scene(self, scene_id: str, source: str) -> Scene:
        """The finished scene: the grid as it is now, with a room polygon per box."""
        resolution = self.raster.resolution
        origin = (-self.raster.margin * resolution, -self.raster.margin * resolution)
        rooms = [
            Room(name, room_polygon(e, origin, resolution)) for name, e in zip(self.labels, self.extents, strict=True)
        ]
        grid = GridSpec(resolution, origin, self.structure.shape)
        return Scene(scene_id, grid, self.structure, rooms=rooms, source=source)


def lay_out_floor(
    rng: np.random.Generator, plan: Plan, names: list[str], resolution: float, wall: float | None = None
) -> Floor:
    """Draw ``plan`` on a structure grid at ``resolution`` (walls ``wall`` metres thick, else of a random thickness),
    before any door is cut."""
    t = max(1, round((rng.uniform(*WALL_THICKNESS) if wall is None else wall) / resolution))
    raster = Raster(resolution, t, t + round(OUTSIDE_MARGIN / resolution), max(1, round(JAMB / resolution)))
    boxes = [raster.snap(b) for b in plan.rooms] + [raster.snap(b) for b in plan.corridors]
    outline = raster.snap(Box(0.0, 0.0, plan.width, plan.height))
    shape = (outline.r1 + raster.margin, outline.c1 + raster.margin)
    structure = np.full(shape, Material.UNKNOWN, dtype=np.uint8)
    structure[outline.r0 - raster.h : outline.r1 - raster.h + t, outline.c0 - raster.h : outline.c1 - raster.h + t] = (
        Material.WALL
    )
    extents = [[*raster.interior(b.r0, b.r1), *raster.interior(b.c0, b.c1)] for b in boxes]
    for r_lo, r_hi, c_lo, c_hi in extents:
        structure[r_lo:r_hi, c_lo:c_hi] = Material.FREE
    open_corridors(structure, raster, boxes, len(plan.rooms), extents)
    return Floor(raster, boxes, structure, extents, names + [HALLWAY] * len(plan.corridors))


def _build_scene(rng: np.random.Generator, plan: Plan, names: list[str], resolution: float, scene_id: str) -> Scene:
    floor = lay_out_floor(rng, plan, names, resolution)
    for a, b in _door_pairs(rng, floor.raster, floor.boxes, floor.labels, len(plan.rooms)):
        edge = shared_edge(floor.boxes[a], floor.boxes[b])
        assert edge is not None
        cut_door(rng, floor.structure, floor.raster, edge)
    return floor.scene(scene_id, "procedural")


def open_corridors(
    structure: NDArray[np.uint8], raster: Raster, boxes: list[CellBox], first: int, extents: list[list[int]]
) -> None:
    """Remove the walls between touching corridors; the later corridor's extent takes in the opened strip."""
    for a in range(first, len(boxes)):
        for b in range(a + 1, len(boxes)):
            edge = shared_edge(boxes[a], boxes[b])
            if edge is None:
                continue
            raster.paint(structure, edge, *raster.interior(edge.lo, edge.hi), Material.FREE)
            strip = (edge.line - raster.h, edge.line - raster.h + raster.t)
            axis = 2 if edge.vertical else 0
            extents[b][axis] = min(extents[b][axis], strip[0])
            extents[b][axis + 1] = max(extents[b][axis + 1], strip[1])


def door_capacity(raster: Raster, edge: Edge) -> int:
    """Widest door (cells) that fits in ``edge`` with its jambs and a cell of wall either side."""
    lo, hi = raster.interior(edge.lo, edge.hi)
    return hi - lo - 2 * raster.jamb - 2


def _door_pairs(
    rng: np.random.Generator, raster: Raster, boxes: list[CellBox], labels: list[str], n_rooms: int
) -> list[tuple[int, int]]:
    """Doors forming a spanning tree from the corridors (or the largest room), plus a few open-plan loops.

    Boxes ``0..n_rooms-1`` are rooms, the rest corridors. Rooms on a corridor open onto it; the others open
    onto a neighbour that is already reachable.
    """
    edges = [
        (a, b)
        for a in range(n_rooms)
        for b in range(a + 1, len(boxes))
        if (edge := shared_edge(boxes[a], boxes[b])) is not None and door_capacity(raster, edge) >= raster.min_door
    ]
    corridors = set(range(n_rooms, len(boxes)))
    largest = max(range(n_rooms), key=lambda k: (boxes[k].c1 - boxes[k].c0) * (boxes[k].r1 - boxes[k].r0))
    reached = set(corridors) if corridors else {largest}
    doors: list[tuple[int, int]] = []
    while len(reached) < len(boxes):
        frontier = [p for p in edges if (p[0] in reached) != (p[1] in reached)]
        if not frontier:
            raise RuntimeError("procedural plan has a room that no door can reach")
        pool = [p for p in frontier if p[1] in corridors] or frontier
        pick = pool[int(rng.integers(len(pool)))]
        doors.append(pick)
        reached.update(pick)
    loops = [
        p
        for p in edges
        if p not in doors and p[1] < n_rooms and frozenset((labels[p[0]], labels[p[1]])) in _EXTRA_DOOR_PAIRS
    ]
    return doors + [p for p in loops if rng.random() < 0.5]


def cut_door(rng: np.random.Generator, structure: NDArray[np.uint8], raster: Raster, edge: Edge) -> None:
    """Open a 0.8-1.1 m door at a random place along ``edge`` and frame it with door-frame jambs."""
    lo, hi = raster.interior(edge.lo, edge.hi)
    w_max = min(math.floor(_DOOR_WIDTH[1] / raster.resolution + 1e-9), door_capacity(raster, edge))
    width = int(rng.integers(raster.min_door, w_max + 1))
    start = int(rng.integers(lo + raster.jamb + 1, hi - raster.jamb - 1 - width + 1))
    raster.paint(structure, edge, start, start + width, Material.FREE)
    raster.paint(structure, edge, start - raster.jamb, start, Material.DOOR_FRAME)
    raster.paint(structure, edge, start + width, start + width + raster.jamb, Material.DOOR_FRAME)


def room_polygon(extent: list[int], origin: tuple[float, float], resolution: float) -> tuple[tuple[float, float], ...]:
    r_lo, r_hi, c_lo, c_hi = extent
    x0, x1 = origin[0] + c_lo * resolution, origin[0] + c_hi * resolution
    y0, y1 = origin[1] + r_lo * resolution, origin[1] + r_hi * resolution
    return ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
