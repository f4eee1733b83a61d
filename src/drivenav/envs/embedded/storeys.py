"""HM3D-like homes of one to three storeys joined by staircases (the scene part ``storeys``; docs/floors.md).

A home of one storey is a home of :mod:`drivenav.envs.embedded.homes`. A taller one keeps that layout's frame on
every storey -- a hall *spine* along the house, the public band on one side, the private band on the other, cut
into blocks by halls that leave the spine -- so that walls and halls stack as load-bearing walls do, and each
storey gets its own rooms, doors and objects, zoned as real homes are (after ProcTHOR's house specs,
allenai/procthor): the ground floor holds the open-plan kitchen, dining and living rooms with laundry, garage, a
study and a bathroom; upper floors hold bedrooms (a primary one first), bathrooms, closets, a playroom or a study.

Each staircase stands in a *stair hall*: a hall from the spine through the private band, split lengthwise into
the stairs' strip and a passage beside it (no door opens into the strip). The stairs rise from the spine's end of
the strip toward the outer wall, straight or with a half landing in line, and leave at least
:attr:`StoreysConfig.exit_landing` of floor before that wall; the storey above has its stairwell over the strip
(:mod:`drivenav.envs.embedded.building`). A three-storey home has a stair hall per storey pair, side by side
along the spine, so that no flight stands in the stairwell of another.

Dimensions: floor-to-floor heights of 2.8-3.2 m; the fewest risers of at most 0.19 m that climb a storey (0.175-0.19 m:
the 15-20 cm of real stairs, under habitat-sim's 0.2 m climb), goings of 0.25-0.30 m (a ramp of 33-41 degrees, under the
navmesh's 45), stair halls 0.9-1.1 m wide (the stairs between their walls 0.75-1.0 m). Everything is drawn from
``numpy.random.default_rng(seed)``, so a seed always gives the same home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import (
    SLAB_THICKNESS,
    Box3,
    Building,
    Flight,
    Landing,
    Staircase,
    Storey,
    stair_ends,
)
from drivenav.envs.embedded.homes import (
    CORE,
    DEFAULT_HOMES,
    HomesConfig,
    build_floor,
    draw_area,
    home_layout,
    match_by_size,
    public_widths,
)
from drivenav.envs.embedded.placement import place_objects
from drivenav.envs.embedded.procedural import (
    MIN_BLOCK,
    WALL_THICKNESS,
    Box,
    Floor,
    Plan,
    Transform,
    allocate_cells,
    apply_transform,
    draw_transform,
    side_blocks,
    split_box,
    transform_box,
)
from drivenav.envs.embedded.scene import Material
from drivenav.errors import InputError

Weighted = tuple[tuple[str, float, int], ...]
"""Room types with a weight and the most a storey may have."""


@dataclass(frozen=True)
class StoreysConfig:
    """How homes of several storeys are drawn (the module's docstring gives the sources of the dimensions).

    ``storeys``: the chances of one, two and three storeys (60 % of homes have several: HM3D val's episodes are
    65 % in multi-storey buildings, ASCENT's count). ``storey_height``: floor to floor. ``max_riser``, ``going``,
    ``stair_width``, ``passage_width``: the stairs and the passage beside them; ``p_landing``: stairs with a half
    landing. ``exit_landing``: floor left between the top of the stairs and the outer wall. ``ground_rooms`` /
    ``upper_public`` / ``upper_private``: how many rooms the ground floor's private band, an upper floor's public
    band and its private band hold (at least one per block), drawn from the weighted types below them.
    """

    homes: HomesConfig = DEFAULT_HOMES
    storeys: tuple[float, float, float] = (0.4, 0.45, 0.15)
    storey_height: tuple[float, float] = (2.8, 3.2)
    max_riser: float = 0.19
    going: tuple[float, float] = (0.25, 0.30)
    stair_width: tuple[float, float] = (0.9, 1.1)
    passage_width: tuple[float, float] = (1.0, 1.3)
    p_landing: float = 0.4
    exit_landing: float = 1.0
    ground_rooms: tuple[int, int] = (2, 4)
    upper_public: tuple[int, int] = (2, 4)
    upper_private: tuple[int, int] = (3, 6)
    ground_types: Weighted = (
        ("bathroom", 2.0, 1),
        ("office", 1.5, 1),
        ("closet", 1.0, 2),
        ("bedroom", 1.0, 1),
        ("gym", 0.5, 1),
    )
    upper_public_types: Weighted = (("bedroom", 3.0, 3), ("playroom", 0.8, 1), ("office", 1.0, 1))
    upper_private_types: Weighted = (
        ("bedroom", 3.0, 4),
        ("bathroom", 2.5, 3),
        ("closet", 1.5, 3),
        ("office", 0.6, 1),
        ("laundry room", 0.3, 1),
    )


DEFAULT_STOREYS = StoreysConfig()
ATTEMPTS = 20  # layouts drawn (from the same generator) before a seed is given up


@dataclass(frozen=True)
class _StairSpec:
    """One staircase's drawn dimensions."""

    risers: int
    riser: float
    going: float
    width: float
    passage: float
    landing: bool

    @property
    def run(self) -> float:
        """Horizontal length of its flights and landing."""
        if self.landing:
            return (self.risers - 2) * self.going + self.width
        return (self.risers - 1) * self.going


@dataclass
class _Frame:
    """What every storey shares: the plan's size, the spine, the halls (stair halls as strip and passage) and the
    private band's blocks."""

    length: float
    depth: float
    spine: Box
    public_depth: float
    halls: list[Box]
    strips: list[int]  # per staircase, the index of its strip in ``halls``
    blocks: list[tuple[Box, tuple[bool, bool, bool, bool]]] = field(default_factory=list)

    @property
    def height(self) -> float:
        return self.spine.y1 + self.public_depth


def generate_storeyed_home(seed: int, config: StoreysConfig = DEFAULT_STOREYS, resolution: float = 0.05) -> Building:
    """A home of one to three storeys, fully determined by ``seed`` (the module's docstring)."""
    from drivenav.envs.embedded.library import storeyed_scene_id

    if not 0.01 <= resolution <= 0.2:
        raise InputError("generate_storeyed_home", "resolution", "metres per cell in [0.01, 0.2]", resolution)
    rng = np.random.default_rng(seed)
    scene_id = storeyed_scene_id(seed)
    count = 1 + int(rng.choice(3, p=np.asarray(config.storeys) / sum(config.storeys)))
    height = float(rng.uniform(*config.storey_height))
    if count == 1:
        return _one_storey(rng, config, scene_id, resolution, height)
    specs = [_draw_stairs(rng, config, height) for _ in range(count - 1)]
    for _ in range(ATTEMPTS):
        try:
            return _several_storeys(rng, config, scene_id, resolution, height, specs)
        except RuntimeError:  # a plan with a room no door can reach: draw another
            continue
    raise RuntimeError(f"{scene_id}: no layout in {ATTEMPTS} attempts")


def _one_storey(
    rng: np.random.Generator, config: StoreysConfig, scene_id: str, resolution: float, height: float
) -> Building:
    plan, names, core = home_layout(rng, config.homes)
    plan = apply_transform(plan, draw_transform(rng))
    scene = build_floor(rng, plan, names, core, config.homes.doors, resolution).scene(scene_id, "storeys")
    scene = replace(scene, ceiling_height=height - SLAB_THICKNESS)
    scene = replace(scene, objects=place_objects(scene, rng, free_standing=dict(config.homes.free_standing)))
    return Building(scene_id, (Storey(scene, 0.0),), (), "storeys")


def _draw_stairs(rng: np.random.Generator, config: StoreysConfig, height: float) -> _StairSpec:
    risers = math.ceil(height / config.max_riser - 1e-9)
    return _StairSpec(
        risers=risers,
        riser=height / risers,
        going=float(rng.uniform(*config.going)),
        width=float(rng.uniform(*config.stair_width)),
        passage=float(rng.uniform(*config.passage_width)),
        landing=bool(rng.random() < config.p_landing),
    )


# ----------------------------------------------------------------------------------------------------- layout


def _several_storeys(
    rng: np.random.Generator,
    config: StoreysConfig,
    scene_id: str,
    resolution: float,
    height: float,
    specs: list[_StairSpec],
) -> Building:
    count = len(specs) + 1
    programs = [_ground_program(rng, config), *(_upper_program(rng, config) for _ in range(count - 1))]
    frame = _draw_frame(rng, config, programs, specs)
    transform = draw_transform(rng)
    wall = float(rng.uniform(*WALL_THICKNESS))  # one thickness for every storey: one grid
    walled = frozenset(frame.strips)
    floors: list[Floor] = []
    for j, (public, private) in enumerate(programs):
        plan, names, core = _storey_plan(rng, config, frame, public, private, ground=j == 0)
        plan = apply_transform(plan, transform)
        strips = frozenset(len(plan.rooms) + 1 + s for s in walled)  # after the rooms and the spine
        floors.append(build_floor(rng, plan, names, core, config.homes.doors, resolution, strips, wall))
    storeys = tuple(
        Storey(replace(floor.scene(scene_id, "storeys"), ceiling_height=height - SLAB_THICKNESS), j * height)
        for j, floor in enumerate(floors)
    )
    stairs = tuple(_staircase(k, spec, floors[0], frame, transform, k * height) for k, spec in enumerate(specs))
    bare = Building(scene_id, storeys, stairs, "storeys")
    return _furnish(rng, bare, config)


def _ground_program(
    rng: np.random.Generator, config: StoreysConfig
) -> tuple[list[tuple[str, float]], list[tuple[str, float]]]:
    """The ground floor: the homes' public row (open-plan core with laundry, garage, family room or study) and a
    few rooms of :attr:`StoreysConfig.ground_types` in the private band."""
    homes = config.homes
    kitchen_side = ["laundry room"] if rng.random() < homes.p_laundry else []
    if rng.random() < homes.p_garage:
        kitchen_side.append("garage")
    sides = homes.living_side
    row = [*kitchen_side[::-1], *CORE, sides[int(rng.integers(len(sides)))]]
    private = _draw_types(
        rng, config.ground_types, int(rng.integers(config.ground_rooms[0], config.ground_rooms[1] + 1))
    )
    return _areas(rng, homes, row), _areas(rng, homes, private)


def _upper_program(
    rng: np.random.Generator, config: StoreysConfig
) -> tuple[list[tuple[str, float]], list[tuple[str, float]]]:
    """An upper floor: a primary bedroom and rooms of :attr:`StoreysConfig.upper_public_types` along the spine,
    bedrooms, bathrooms and closets in the private band."""
    lo, hi = config.upper_public
    public = ["bedroom", *_draw_types(rng, config.upper_public_types, int(rng.integers(lo, hi + 1)) - 1)]
    lo, hi = config.upper_private
    private = ["bathroom", *_draw_types(rng, config.upper_private_types, int(rng.integers(lo, hi + 1)) - 1)]
    areas = _areas(rng, config.homes, public)
    areas[0] = ("bedroom", float(rng.uniform(*config.homes.primary_bedroom_area)))
    return areas, _areas(rng, config.homes, private)


def _draw_types(rng: np.random.Generator, types: Weighted, count: int) -> list[str]:
    chosen: list[str] = []
    for _ in range(count):
        allowed = [(t, w) for t, w, cap in types if chosen.count(t) < cap]
        weights = np.array([w for _, w in allowed])
        chosen.append(allowed[int(rng.choice(len(allowed), p=weights / weights.sum()))][0])
    return chosen


def _areas(rng: np.random.Generator, config: HomesConfig, types: list[str]) -> list[tuple[str, float]]:
    return [(t, draw_area(rng, config, t)) for t in types]


def _draw_frame(
    rng: np.random.Generator,
    config: StoreysConfig,
    programs: list[tuple[list[tuple[str, float]], list[tuple[str, float]]]],
    specs: list[_StairSpec],
) -> _Frame:
    """The shared frame: the private band deep enough for the longest stairs and their exit landing; one regular
    hall per about 4.5 private rooms of the fullest storey besides the stair halls, in random order along the
    spine; the length that holds the largest private band."""
    homes = config.homes
    spine_width = float(rng.uniform(*homes.hall_width))
    need = max(s.run for s in specs) + config.exit_landing + 0.3
    depth = float(rng.uniform(max(homes.private_depth[0], need), max(homes.private_depth[1], need)))
    n_private = max(len(private) for _, private in programs)
    regular = [float(w) for w in rng.uniform(*homes.hall_width, max(1, round(n_private / 4.5)) - 1)]
    widths = regular + [s.width + s.passage for s in specs]
    order = [int(k) for k in rng.permutation(len(widths))]
    widths = [widths[k] for k in order]
    private_area = max(sum(a for _, a in private) for _, private in programs)
    min_length = max(sum(widths) + (len(widths) + 1) * MIN_BLOCK, len(programs[0][0]) * homes.min_public_width)
    length = max(private_area / depth + sum(widths), min_length)
    public_area = sum(a for _, a in programs[0][0])
    public_depth = float(np.clip(public_area / length, *homes.public_depth))
    spine = Box(0.0, depth, length, depth + spine_width)
    plan = Plan(length, depth + spine_width + public_depth, [], [spine])
    blocks = side_blocks(rng, plan, (0.0, length, 0.0, depth), np.asarray(widths), 0)
    halls: list[Box] = []
    strip_of: dict[int, int] = {}
    for k, hall in enumerate(plan.corridors[1:]):
        stair = order[k] - len(regular)
        if stair < 0:
            halls.append(hall)
            continue
        spec = specs[stair]
        left = bool(rng.random() < 0.5)
        cut = hall.x0 + spec.width if left else hall.x1 - spec.width
        strip, passage = Box(hall.x0, hall.y0, cut, hall.y1), Box(cut, hall.y0, hall.x1, hall.y1)
        if not left:
            strip, passage = passage, strip
        strip_of[stair] = len(halls)
        halls.extend((strip, passage))
        blocks = _strip_side_untouched(blocks, k, left)
    by_stair = [strip_of[s] for s in range(len(specs))]
    return _Frame(length, depth, spine, public_depth, halls, by_stair, blocks)


def _strip_side_untouched(
    blocks: list[tuple[Box, tuple[bool, bool, bool, bool]]], hall: int, left: bool
) -> list[tuple[Box, tuple[bool, bool, bool, bool]]]:
    """The blocks with the side that borders hall ``hall``'s stair strip no longer counted as a hall side (no door
    can open there): block ``hall`` lies left of the hall, block ``hall + 1`` right of it."""
    result = list(blocks)
    k = hall if left else hall + 1
    box, (lt, rt, bt, tp) = result[k]
    result[k] = (box, (lt, False, bt, tp) if left else (False, rt, bt, tp))
    return result


def _storey_plan(
    rng: np.random.Generator,
    config: StoreysConfig,
    frame: _Frame,
    public: list[tuple[str, float]],
    private: list[tuple[str, float]],
    ground: bool,
) -> tuple[Plan, list[str], list[int]]:
    """One storey's plan on the frame: its public row along the spine, its private rooms split into the blocks.
    Returns the plan (rooms, then the spine and the halls), the room types and the open-plan core (ground only)."""
    plan = Plan(frame.length, frame.height, [], [frame.spine, *frame.halls])
    widths = public_widths([a for _, a in public], frame.length, config.homes.min_public_width)
    x = 0.0
    for w in widths:
        plan.rooms.append(Box(x, frame.spine.y1, min(x + w, frame.length), frame.height))
        x += w
    names = [t for t, _ in public]
    core = [k for k, t in enumerate(names) if t in CORE][:3] if ground else []
    counts = allocate_cells(max(len(private), len(frame.blocks)), [b.area for b, _ in frame.blocks])
    rooms = list(private)
    while len(rooms) < sum(counts):
        rooms.append(("closet", draw_area(rng, config.homes, "closet")))
    boxes: list[Box] = []
    for (box, touch), k in zip(frame.blocks, counts, strict=True):
        boxes.extend(split_box(rng, box, k, touch))
    plan.rooms.extend(boxes)
    names.extend(match_by_size(rng, boxes, rooms))
    return plan, names, core


# ----------------------------------------------------------------------------------------------------- stairs


def _staircase(
    lower: int, spec: _StairSpec, floor: Floor, frame: _Frame, transform: Transform, base: float
) -> Staircase:
    """The flights (and landing) in a stair strip, from the spine's end of its free interior toward the far end."""
    untransformed = Plan(frame.length, frame.height, [], [])
    strip = transform_box(untransformed, frame.halls[frame.strips[lower]], transform)
    spine = transform_box(untransformed, frame.spine, transform)
    raster, res = floor.raster, floor.raster.resolution
    origin = -raster.margin * res
    cells = raster.snap(strip)
    rows = raster.interior(cells.r0, cells.r1)
    cols = raster.interior(cells.c0, cells.c1)
    along_y = strip.height > strip.width
    lo, hi = rows if along_y else cols
    across = cols if along_y else rows
    centre = origin + (across[0] + across[1]) / 2.0 * res
    width = (across[1] - across[0]) * res
    toward_high = (spine.y0 if along_y else spine.x0) >= (strip.y1 if along_y else strip.x1) - 1e-9
    start = origin + (hi if toward_high else lo) * res
    heading = (90 if not toward_high else 270) if along_y else (0 if not toward_high else 180)
    sign = -1.0 if toward_high else 1.0

    def point(s: float) -> tuple[float, float]:
        along = start + sign * s
        return (centre, along) if along_y else (along, centre)

    dims = {"width": width, "riser": spec.riser, "going": spec.going}
    if not spec.landing:
        return Staircase(lower, (Flight(point(0.0), heading, risers=spec.risers, base=base, **dims),))
    first = spec.risers // 2
    run1 = (first - 1) * spec.going
    flight1 = Flight(point(0.0), heading, risers=first, base=base, **dims)
    a, b = point(run1), point(run1 + width)
    rect = (min(a[0], b[0]), min(a[1], b[1]), max(a[0], b[0]), max(a[1], b[1]))
    if along_y:
        rect = (centre - width / 2.0, rect[1], centre + width / 2.0, rect[3])
    else:
        rect = (rect[0], centre - width / 2.0, rect[2], centre + width / 2.0)
    landing = Landing(rect, flight1.top)
    flight2 = Flight(point(run1 + width), heading, risers=spec.risers - first, base=flight1.top, **dims)
    return Staircase(lower, (flight1, flight2), (landing,))


# ---------------------------------------------------------------------------------------------------- objects


def _furnish(rng: np.random.Generator, building: Building, config: StoreysConfig) -> Building:
    """Objects on every storey, placed as in one-floor homes with the stairs, the stairwells and their railings
    taken for walls (the floor left connected around them) and the floor before and after each flight kept clear;
    instance ids numbered through the building."""
    storeys: list[Storey] = []
    first_id = 0
    railings = building.railings
    for j, storey in enumerate(building.storeys):
        no_floor = building.stair_cells[j] | building.holes[j] | _railing_cells(building, railings[j])
        structure = np.where(no_floor, np.uint8(Material.WALL), storey.plan.structure)
        masked = replace(storey.plan, structure=structure)
        landings = stair_ends(building, j, config.exit_landing)
        objects = place_objects(masked, rng, free_standing=dict(config.homes.free_standing), keep_clear=landings)
        objects = [replace(obj, instance_id=obj.instance_id + first_id) for obj in objects]
        first_id += len(objects)
        storeys.append(Storey(replace(storey.plan, objects=objects), storey.elevation))
    return replace(building, storeys=tuple(storeys))


def _railing_cells(building: Building, boxes: tuple[Box3, ...]) -> NDArray[np.bool_]:
    from drivenav.envs.embedded.levels import box_cells

    return box_cells(building.grid, boxes)
