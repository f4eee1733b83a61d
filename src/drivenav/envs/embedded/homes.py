"""HM3D-like one-floor homes: an open-plan living area, halls with many doors, loops through rooms, 12-20 rooms.

Layout, modelled on how real homes are zoned and on ProcTHOR's house generator (allenai/procthor,
``procthor/generation``: a room spec groups rooms into a public zone and private suites, the floor plan is a
rectangle subdivided by zone, and door rules depend on the room types: kitchen and living room may share an open
connection without a wall, bathrooms open preferably into their suite's bedroom). Here the house is a rectangle
with a hall *spine* along its length. On one side lies the public band, a row of rooms that all open onto the
spine: kitchen, dining room and living room in a row joined by wide openings (the open-plan core, so every one of
them has a way round through the hall), with a laundry and garage beyond the kitchen and a family room, office
or playroom beyond the living room. On the other side lies the private band: bedrooms, bathrooms, closets and
studies in blocks between one to three *landings* (halls leaving the spine at T-junctions), split so that most
rooms open onto a hall and the rest onto a neighbour. Door rules (:mod:`drivenav.envs.embedded.homes_doors`) add
the loops real homes have: ensuite bathrooms that also open onto the hall, corner rooms with a door to the spine
and one to a landing, kitchen - laundry - garage chains, a living room opening into the family room.

Room areas are drawn per type from :class:`HomesConfig` (cited there); the bands' depths and the house's length
follow from them. Walls, doors and rasterising are those of :mod:`drivenav.envs.embedded.procedural`. Objects
come from :func:`drivenav.envs.embedded.placement.place_objects` with today's vocabulary and room priors, plus
free-standing furniture in the open-plan rooms that partly blocks views and passages. Everything is drawn from
``numpy.random.default_rng(seed)``, so a seed always gives the same home.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from drivenav.envs.embedded.homes_doors import DoorRules, choose_doors, cut_opening
from drivenav.envs.embedded.library import home_scene_id
from drivenav.envs.embedded.placement import place_objects
from drivenav.envs.embedded.procedural import (
    MIN_BLOCK,
    Box,
    Floor,
    Plan,
    allocate_cells,
    cut_door,
    lay_out_floor,
    shared_edge,
    side_blocks,
    split_box,
    transform_plan,
)
from drivenav.envs.embedded.scene import Scene
from drivenav.errors import InputError

SQFT = 0.09290304  # m^2 per square foot

CORE = ("kitchen", "dining room", "living room")  # the open-plan row, in this order along the spine


def _sqft(lo: float, hi: float) -> tuple[float, float]:
    return (lo * SQFT, hi * SQFT)


@dataclass(frozen=True)
class HomesConfig:
    """How homes are drawn. Areas are floor areas in m^2 (ranges drawn uniformly), lengths in metres.

    Room areas (``room_area``), from published typical sizes of rooms in average-sized homes:

    - living room 150-400 ft^2, dining room 100-250 ft^2, kitchen 100-200 ft^2, primary bedroom 200-350 ft^2,
      other bedrooms 100-150 ft^2, full bathroom 40-100 ft^2: Sketchplan, *What is the average size of a
      residential room* (https://www.sketchplan.com/what-is-the-average-size-of-a-residential-room/);
    - office, playroom and gym: the secondary bedroom "for children, guests, or a home office", 100-132 ft^2
      (engineerfix.com, *How big is the average room in a house*);
    - laundry room: small 5x8 ft to medium 10x12 ft (designingidea.com, *Laundry room dimensions*);
    - garage: about 400 ft^2 in a 3-bed 2-bath starter home (geteasymove.com, *The average room size in a house
      in United States*), drawn in 320-440 ft^2;
    - closet: around the 7'4" x 5'4" (39 ft^2) walk-in storage closet measured in addicted2decorating.com,
      *Testing out floor plan room sizes in real life*, drawn in 28-50 ft^2.

    ``hall_width``: at least the 42-48 in (1.07-1.22 m) that markanddraft.ca (*How big does my ___ need to be*)
    prefers for hallways, up to 1.5 m for landings. ``rooms``: rooms per home without the halls; with the spine
    and 1-3 landings (fewer where ``most_rooms`` would be passed) a home has 13-20 rooms, the range around
    HM3DSem's 14.4 annotated rooms per scene (arXiv 2210.05633, Table 1). ``private_depth``: depth of the private
    band (deep enough for a front and a back room). ``public_depth``: the public band's depth is its rooms' area
    over the house's length, clipped to this range. ``min_public_width``: narrowest room along the spine.
    ``free_standing``: per room type, categories placed first in the open floor (a sofa or bookshelf dividing
    the living area, a kitchen island), the furniture that partly blocks views and passages.
    """

    room_area: tuple[tuple[str, tuple[float, float]], ...] = (
        ("living room", _sqft(150, 400)),
        ("dining room", _sqft(100, 250)),
        ("kitchen", _sqft(100, 200)),
        ("bedroom", _sqft(100, 150)),
        ("bathroom", _sqft(40, 100)),
        ("office", _sqft(100, 132)),
        ("playroom", _sqft(100, 132)),
        ("gym", _sqft(100, 132)),
        ("laundry room", _sqft(40, 120)),
        ("garage", _sqft(320, 440)),
        ("closet", _sqft(28, 50)),
    )
    primary_bedroom_area: tuple[float, float] = _sqft(200, 350)
    rooms: tuple[int, int] = (12, 17)
    most_rooms: int = 20
    hall_width: tuple[float, float] = (1.1, 1.5)
    private_depth: tuple[float, float] = (5.6, 8.0)
    public_depth: tuple[float, float] = (3.6, 7.0)
    min_public_width: float = 2.6
    # (type, weight, most of that type in a home) for the private rooms beyond a primary bedroom, a bedroom and a
    # bathroom; ProcTHOR's larger specs pair each bedroom with a bathroom.
    private_extra: tuple[tuple[str, float, int], ...] = (
        ("bedroom", 3.0, 5),
        ("bathroom", 2.5, 4),
        ("closet", 1.5, 3),
        ("office", 1.0, 2),
        ("playroom", 0.5, 1),
        ("gym", 0.4, 1),
    )
    p_laundry: float = 0.7  # a laundry room beyond the kitchen
    p_garage: float = 0.3  # a garage at the kitchen's end of the public band
    living_side: tuple[str, ...] = ("living room", "office", "playroom")  # a family room, study or playroom
    p_second_living_side: float = 0.3
    doors: DoorRules = field(default_factory=DoorRules)
    free_standing: tuple[tuple[str, tuple[str, ...]], ...] = (
        ("living room", ("sofa", "bookshelf")),
        ("dining room", ("bookshelf",)),
        ("kitchen", ("kitchen island",)),
    )

    def area_range(self, room_type: str) -> tuple[float, float]:
        return dict(self.room_area)[room_type]


DEFAULT_HOMES = HomesConfig()


@dataclass(frozen=True)
class _Program:
    """The rooms of one home: the public band's row (left to right) and the private rooms, with drawn areas."""

    public: list[tuple[str, float]]
    private: list[tuple[str, float]]


def generate_home(seed: int, config: HomesConfig = DEFAULT_HOMES, resolution: float = 0.05) -> Scene:
    """A one-floor home with 12-20 rooms (halls included), doors, loops and objects, fully determined by ``seed``.

    The home lies in ``x, y >= 0`` (the outer walls' centre lines start at the world origin).
    """
    if not 0.01 <= resolution <= 0.2:
        raise InputError("generate_home", "resolution", "metres per cell in [0.01, 0.2]", resolution)
    rng = np.random.default_rng(seed)
    plan, names, core = home_layout(rng, config)
    plan = transform_plan(rng, plan)
    scene = _build(rng, plan, names, core, config, resolution, home_scene_id(seed))
    objects = place_objects(scene, rng, free_standing=dict(config.free_standing))
    return replace(scene, objects=objects)


def home_layout(rng: np.random.Generator, config: HomesConfig = DEFAULT_HOMES) -> tuple[Plan, list[str], list[int]]:
    """A home's plan in metres before its mirroring (rooms and halls), its room types and its open-plan core."""
    return _layout(rng, _draw_program(rng, config), config)


# --------------------------------------------------------------------------------------------- program


def _draw_program(rng: np.random.Generator, config: HomesConfig) -> _Program:
    """Room types and areas: the open-plan core with its neighbours, then private rooms up to the drawn count."""
    total = int(rng.integers(config.rooms[0], config.rooms[1] + 1))
    kitchen_side = ["laundry room"] if rng.random() < config.p_laundry else []
    if rng.random() < config.p_garage:
        kitchen_side.append("garage")
    sides = config.living_side
    living_side = [sides[int(rng.integers(len(sides)))]]
    if rng.random() < config.p_second_living_side:
        living_side.append(sides[int(rng.integers(len(sides)))])
    row = [*kitchen_side[::-1], *CORE, *living_side]
    private = ["bedroom", "bedroom", "bathroom"]
    while len(row) + len(private) < total:
        taken = row + private
        allowed = [(t, w) for t, w, cap in config.private_extra if taken.count(t) < cap]
        weights = np.array([w for _, w in allowed])
        private.append(allowed[int(rng.choice(len(allowed), p=weights / weights.sum()))][0])
    areas = [draw_area(rng, config, t) for t in row]
    private_areas = [rng.uniform(*config.primary_bedroom_area)] + [draw_area(rng, config, t) for t in private[1:]]
    return _Program(list(zip(row, areas, strict=True)), list(zip(private, private_areas, strict=True)))


def draw_area(rng: np.random.Generator, config: HomesConfig, room_type: str) -> float:
    return float(rng.uniform(*config.area_range(room_type)))


# ---------------------------------------------------------------------------------------------- layout


def _landing_count(n_private: int, n_rooms: int, most_rooms: int) -> int:
    """Landings (halls off the spine into the private band): one per about 4.5 private rooms, at least one, and
    no more than keeps the home (spine and landings included) within ``most_rooms`` rooms."""
    return max(1, min(round(n_private / 4.5), most_rooms - n_rooms - 1))


def _layout(rng: np.random.Generator, program: _Program, config: HomesConfig) -> tuple[Plan, list[str], list[int]]:
    """The plan in metres: private band ``[0, depth)``, spine above it, public band on top.

    Returns the plan (rooms: public row first, then private rooms; corridors: spine first, then landings), the
    room types in room order, and the indices of the open-plan core rooms.
    """
    spine_width = float(rng.uniform(*config.hall_width))
    n_landings = _landing_count(len(program.private), len(program.public) + len(program.private), config.most_rooms)
    landing_widths = rng.uniform(*config.hall_width, n_landings)
    depth = float(rng.uniform(*config.private_depth))
    private_area = sum(a for _, a in program.private)
    min_length = max(
        float(landing_widths.sum()) + (n_landings + 1) * MIN_BLOCK,
        len(program.public) * config.min_public_width,
    )
    length = max(private_area / depth + float(landing_widths.sum()), min_length)
    public_area = sum(a for _, a in program.public)
    public_depth = float(np.clip(public_area / length, *config.public_depth))
    y_spine = depth + spine_width
    plan = Plan(length, y_spine + public_depth, [], [Box(0.0, depth, length, y_spine)])

    widths = public_widths([a for _, a in program.public], length, config.min_public_width)
    x = 0.0
    for w in widths:
        plan.rooms.append(Box(x, y_spine, min(x + w, length), plan.height))
        x += w
    names = [t for t, _ in program.public]
    core = [k for k, t in enumerate(names) if t in CORE][:3]

    blocks = side_blocks(rng, plan, (0.0, length, 0.0, depth), landing_widths, 0)
    private_boxes: list[Box] = []
    for (box, touch), k in zip(blocks, allocate_cells(len(program.private), [b.area for b, _ in blocks]), strict=True):
        private_boxes.extend(split_box(rng, box, k, touch))
    plan.rooms.extend(private_boxes)
    names.extend(match_by_size(rng, private_boxes, program.private))
    return plan, names, core


def public_widths(areas: list[float], length: float, minimum: float) -> list[float]:
    """Widths along the spine proportional to the rooms' areas, none below ``minimum``, summing to ``length``."""
    widths = np.array(areas) * length / sum(areas)
    for _ in range(len(areas)):
        small = widths < minimum
        if not small.any():
            break
        widths[small] = minimum
        rest = length - minimum * small.sum()
        widths[~small] *= rest / widths[~small].sum()
    return [float(w) for w in widths]


def match_by_size(rng: np.random.Generator, boxes: list[Box], rooms: list[tuple[str, float]]) -> list[str]:
    """Room types for ``boxes``: the largest box gets the type drawn largest (areas jittered by 20 %)."""
    keys = np.array([a for _, a in rooms]) * rng.lognormal(0.0, 0.2, len(rooms))
    types = [rooms[i][0] for i in np.argsort(-keys, kind="stable")]
    order = sorted(range(len(boxes)), key=lambda k: -boxes[k].area)
    names = [""] * len(boxes)
    for k, t in zip(order, types, strict=True):
        names[k] = t
    return names


# ------------------------------------------------------------------------------------------- rasterising


def _build(
    rng: np.random.Generator,
    plan: Plan,
    names: list[str],
    core: list[int],
    config: HomesConfig,
    resolution: float,
    scene_id: str,
) -> Scene:
    """Walls, halls opened into each other, doors and open-plan openings on the structure grid; room polygons."""
    return build_floor(rng, plan, names, core, config.doors, resolution).scene(scene_id, "homes")


def build_floor(
    rng: np.random.Generator,
    plan: Plan,
    names: list[str],
    core: list[int],
    rules: DoorRules,
    resolution: float,
    walled: frozenset[int] = frozenset(),
    wall: float | None = None,
) -> Floor:
    """A home plan on the structure grid: walls (``wall`` metres thick, else of a random thickness), halls opened
    into each other, doors by ``rules`` (none into the ``walled`` boxes) and open-plan openings between the ``core``
    rooms."""
    floor = lay_out_floor(rng, plan, names, resolution, wall)
    n_rooms = len(plan.rooms)
    for door in choose_doors(rng, rules, floor.raster, floor.boxes, floor.labels, n_rooms, core, walled):
        edge = shared_edge(floor.boxes[door.a], floor.boxes[door.b])
        assert edge is not None
        if door.open:
            cut_opening(rng, floor.structure, floor.raster, edge, rules.open_width)
        else:
            cut_door(rng, floor.structure, floor.raster, edge)
    return floor
