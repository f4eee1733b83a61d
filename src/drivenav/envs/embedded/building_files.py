"""Buildings from files: a *building directory* holds ``building.yaml``, which stacks floor plans (ROS maps, as map
scenes give them) at their elevations and joins them by staircases (docs/scenes.md, "Buildings from files")::

    storeys:                    # from the ground floor up
      - plan: ground            # a map scene directory, or a map YAML, relative to this file
        elevation: 0.0          # metres; the ground floor is 0
      - plan: upper/map.yaml
        elevation: 3.0
    stairs:
      - lower: 0                # rises from storeys[0] to storeys[1]
        flights:                # in the order they are climbed
          - {foot: [1.5, 0.6], heading: 0, width: 1.0, risers: 16, going: 0.25}
        landings: []            # one between each two flights

Heights are derived, so that a staircase is written once and cannot contradict itself: the first flight starts on
the lower floor, each later one at the height of the landing before it, which lies at the top of the flight below
it (a landing's optional ``height`` must agree); a flight without ``riser`` gets the storey height split evenly over
every riser of its staircase.

What a building must be, each broken rule one :class:`~drivenav.errors.InputError` naming the file and the field:
storeys at least :data:`MIN_STOREY_HEIGHT` apart on one grid; flights with risers the agent can climb and ramps it
can walk, that climb from the lower floor to the upper one, stand on free floor and lead from free floor to free
floor (:data:`ARRIVAL_DEPTH` of it at each end), joined by the landings between them; no object of an
``objects.json`` on the stairs or over a stairwell. Without ``objects.json`` a storey's objects are placed as a map
scene's are, with the stairs, the stairwells and their railings kept clear; instance ids run through the building,
storey by storey.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import (
    HEADINGS,
    Building,
    Flight,
    Landing,
    Rect,
    Staircase,
    Storey,
    rect_cells,
    stair_ends,
)
from drivenav.envs.embedded.levels import MAX_STEP, box_cells
from drivenav.envs.embedded.placement import place_objects
from drivenav.envs.embedded.rosmap import OBJECTS_FILE, MapPlan, read_map_plan, scene_rng
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.errors import InputError
from drivenav.grid import GridSpec
from drivenav.validation import Fields, read_yaml

BUILDING_FILE = "building.yaml"
MIN_STOREY_HEIGHT = 2.4
"""Metres from one floor to the next at least: a 2.2 m ceiling (about the lowest building codes allow in a room:
7 ft, 2.13 m, in the US IRC) under the 0.2 m slab; the walking surfaces of :mod:`~drivenav.envs.embedded.levels`
count on storeys this far apart."""
MAX_RISER = MAX_STEP  # metres: habitat-sim's navmesh climb; a higher step is a wall to the agent
MAX_SLOPE = 1.0  # rise over run of a flight's ramp: habitat-sim's navmesh walks slopes up to 45 degrees
CLIMB_TOLERANCE = 0.05  # metres a flight's top may miss the floor or landing it arrives on (a step, well in the climb)
JOIN_TOLERANCE = 0.01  # metres: a landing holds the edges of the flights it joins (a one-cell gap breaks the ramp)
ARRIVAL_DEPTH = 0.25  # metres of free floor before the first riser and beyond the last flight: one forward step
CLEAR_DEPTH = 1.0  # metres of floor at either end of the stairs no placed object covers (the generated homes' 1 m)

_TOP_KEYS = frozenset({"storeys", "stairs"})
_STOREY_KEYS = frozenset({"plan", "elevation"})
_STAIR_KEYS = frozenset({"lower", "flights", "landings"})
_FLIGHT_KEYS = frozenset({"foot", "heading", "width", "risers", "riser", "going"})
_FLIGHT_REQUIRED = ("foot", "heading", "width", "risers", "going")
_LANDING_KEYS = frozenset({"rect", "height"})
_EPS = 1e-9  # metres: rounding in derived coordinates


@dataclass(frozen=True)
class StoreyEntry:
    """One storey of a building.yaml: its floor plan (a map directory or YAML) and its floor's elevation."""

    plan: Path
    elevation: float


@dataclass(frozen=True)
class BuildingFile:
    """The validated content of a building.yaml, its staircases with every height derived."""

    path: Path
    storeys: tuple[StoreyEntry, ...]
    stairs: tuple[Staircase, ...]

    @property
    def scene_id(self) -> str:
        """The building directory's name, as a map scene's id is its directory's."""
        return self.path.resolve().parent.name


@dataclass(frozen=True)
class _FlightEntry:
    """A flight as the file gives it: ``riser`` None where the storey height is split evenly."""

    foot: tuple[float, float]
    heading: int
    width: float
    risers: int
    riser: float | None
    going: float

    def flight(self, even_riser: float, base: float) -> Flight:
        riser = self.riser if self.riser is not None else even_riser
        return Flight(self.foot, self.heading, self.width, self.risers, riser, self.going, base)


# ---------------------------------------------------------------------------------------------------- locating


def find_building_yaml(path: str | Path) -> Path | None:
    """The building.yaml of a building directory (or that file itself); None for anything else."""
    path = Path(path)
    candidate = path / BUILDING_FILE if path.is_dir() else path
    return candidate if candidate.name == BUILDING_FILE and candidate.is_file() else None


# ------------------------------------------------------------------------------------------- building.yaml


def read_building_yaml(path: str | Path) -> BuildingFile:
    """Read and validate a building.yaml: its fields, the storeys' order and the staircases' geometry (the floor
    plans themselves are read by :func:`load_building`)."""
    path = Path(path)
    fields = Fields(path)
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise fields.error("", "a YAML mapping with the keys storeys and stairs", type(doc).__name__)
    fields.mapping(doc, "", _TOP_KEYS, ("storeys",))
    items = fields.sequence(doc["storeys"], "storeys", 1, "a non-empty list of storeys (plan, elevation)")
    storeys = tuple(_read_storey(fields, f"storeys[{j}]", item, path.parent) for j, item in enumerate(items))
    _check_elevations(fields, storeys)
    elevations = [s.elevation for s in storeys]
    stairs = fields.sequence(doc.get("stairs", []), "stairs")
    return BuildingFile(
        path, storeys, tuple(_read_staircase(fields, f"stairs[{i}]", v, elevations) for i, v in enumerate(stairs))
    )


def _read_storey(fields: Fields, name: str, value: Any, directory: Path) -> StoreyEntry:
    entry = fields.mapping(value, name, _STOREY_KEYS, ("plan", "elevation"))
    plan = directory / fields.text(entry["plan"], f"{name}.plan")
    if not plan.exists():
        expected = "a map scene directory or a map YAML, relative to the building directory"
        raise fields.error(f"{name}.plan", expected, entry["plan"])
    return StoreyEntry(plan, fields.number(entry["elevation"], f"{name}.elevation"))


def _check_elevations(fields: Fields, storeys: tuple[StoreyEntry, ...]) -> None:
    """The ground floor at 0, every other at least :data:`MIN_STOREY_HEIGHT` above the one below."""
    if storeys[0].elevation != 0.0:
        raise fields.error(
            "storeys[0].elevation", "0: heights are measured from the ground floor", storeys[0].elevation
        )
    for j in range(1, len(storeys)):
        lowest = storeys[j - 1].elevation + MIN_STOREY_HEIGHT
        if storeys[j].elevation < lowest - _EPS:
            expected = f"at least {lowest:g} m: storeys from the ground up, each {MIN_STOREY_HEIGHT:g} m or more above"
            raise fields.error(f"storeys[{j}].elevation", f"{expected} the one below", storeys[j].elevation)


def _read_staircase(fields: Fields, name: str, value: Any, elevations: list[float]) -> Staircase:
    entry = fields.mapping(value, name, _STAIR_KEYS, ("lower", "flights"))
    lower = _read_lower(fields, f"{name}.lower", entry["lower"], len(elevations))
    expected = "a non-empty list of flights, in the order they are climbed"
    raw = fields.sequence(entry["flights"], f"{name}.flights", 1, expected)
    entries = [_read_flight(fields, f"{name}.flights[{k}]", item) for k, item in enumerate(raw)]
    landings = fields.sequence(entry.get("landings", []), f"{name}.landings")
    if len(landings) != len(entries) - 1:
        expected = f"one landing between each two flights ({len(entries)} flights: {len(entries) - 1} landings)"
        raise fields.error(f"{name}.landings", expected, len(landings))
    stair = _stack(fields, name, lower, entries, landings, elevations)
    _check_joins(fields, name, stair)
    bottom, top, reached = elevations[lower], elevations[lower + 1], stair.flights[-1].top
    if abs(reached - top) > CLIMB_TOLERANCE:
        floors = f"storeys[{lower}]'s floor ({bottom:g} m) to storeys[{lower + 1}]'s ({top:g} m)"
        expected = f"flights that climb from {floors}, within {CLIMB_TOLERANCE:g} m"
        raise fields.error(f"{name}.flights", expected, f"a climb to {reached:.3f} m")
    return stair


def _stack(
    fields: Fields, name: str, lower: int, entries: list[_FlightEntry], landings: list[Any], elevations: list[float]
) -> Staircase:
    """The flights from the lower floor up, each starting at the height of the landing before it (the first on the
    floor), each landing at the top of the flight below it."""
    even = (elevations[lower + 1] - elevations[lower]) / sum(e.risers for e in entries)
    flights: list[Flight] = []
    joins: list[Landing] = []
    base = elevations[lower]
    for k, flight_entry in enumerate(entries):
        flights.append(flight_entry.flight(even, base))
        _check_flight(fields, f"{name}.flights[{k}]", flights[-1], flight_entry.riser is None)
        if k < len(landings):
            joins.append(_read_landing(fields, f"{name}.landings[{k}]", landings[k], flights[-1]))
            base = joins[-1].height
    return Staircase(lower, tuple(flights), tuple(joins))


def _read_lower(fields: Fields, name: str, value: Any, storeys: int) -> int:
    lower = fields.integer(value, name, minimum=0)
    if lower >= storeys - 1:
        above = f"0 to {storeys - 2}" if storeys > 1 else "none: the building has one storey"
        raise fields.error(name, f"the index of a storey with one above it ({above})", lower)
    return lower


def _read_flight(fields: Fields, name: str, value: Any) -> _FlightEntry:
    entry = fields.mapping(value, name, _FLIGHT_KEYS, _FLIGHT_REQUIRED)
    foot = fields.numbers(entry["foot"], f"{name}.foot", 2, "a point [x, y]")
    heading = fields.number(entry["heading"], f"{name}.heading")
    fields.choice(heading, f"{name}.heading", HEADINGS, "one of 0, 90, 180, 270 (degrees from +x, counter-clockwise)")
    riser = entry.get("riser")
    return _FlightEntry(
        foot=(foot[0], foot[1]),
        heading=int(heading),
        width=fields.number(entry["width"], f"{name}.width", positive=True),
        risers=fields.integer(entry["risers"], f"{name}.risers", minimum=2),
        riser=None if riser is None else fields.number(riser, f"{name}.riser", positive=True),
        going=fields.number(entry["going"], f"{name}.going", positive=True),
    )


def _check_flight(fields: Fields, name: str, flight: Flight, even: bool) -> None:
    """Steps the agent can climb and a ramp it can walk up (habitat-sim's navmesh limits)."""
    if flight.riser > MAX_RISER + _EPS:
        if even:
            expected = f"more risers: the storey height over the staircase's risers gives steps above {MAX_RISER:g} m"
            raise fields.error(f"{name}.risers", f"{expected} (habitat-sim's climb)", flight.risers)
        raise fields.error(f"{name}.riser", f"at most {MAX_RISER:g} m (habitat-sim's climb)", flight.riser)
    if flight.slope > MAX_SLOPE + _EPS:
        least = flight.rise / (MAX_SLOPE * (flight.risers - 1))
        degrees = math.degrees(math.atan(flight.slope))
        expected = f"at least {least:.3f} m: a ramp no steeper than 45 degrees (habitat-sim's navmesh)"
        raise fields.error(f"{name}.going", expected, f"{flight.going:g} ({degrees:.0f} degrees)")


def _read_landing(fields: Fields, name: str, value: Any, below: Flight) -> Landing:
    entry = fields.mapping(value, name, _LANDING_KEYS, ("rect",))
    x0, y0, x1, y1 = fields.numbers(entry["rect"], f"{name}.rect", 4, "a rectangle [x0, y0, x1, y1], x0 < x1, y0 < y1")
    if not (x0 < x1 and y0 < y1):
        raise fields.error(f"{name}.rect", "a rectangle [x0, y0, x1, y1], x0 < x1, y0 < y1", entry["rect"])
    height = below.top
    if "height" in entry:
        height = fields.number(entry["height"], f"{name}.height")
        if abs(height - below.top) > CLIMB_TOLERANCE:
            expected = f"the top of the flight below it, {below.top:.3f} m, within {CLIMB_TOLERANCE:g} m (or no height)"
            raise fields.error(f"{name}.height", expected, height)
    return Landing((x0, y0, x1, y1), height)


def _check_joins(fields: Fields, name: str, stair: Staircase) -> None:
    """Each landing holds the top edge of the flight before it and the foot edge of the one after it."""
    for k, landing in enumerate(stair.landings):
        before, after = stair.flights[k], stair.flights[k + 1]
        ends = (*_edge(before, before.run), *_edge(after, 0.0))
        if not all(_holds(landing.rect, point) for point in ends):
            expected = f"a rectangle holding the top edge of flights[{k}] and the foot edge of flights[{k + 1}]"
            raise fields.error(f"{name}.landings[{k}].rect", expected, list(landing.rect))


def _edge(flight: Flight, along: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The end points of the flight's cross-section ``along`` metres from its foot."""
    x0, y0, x1, y1 = flight.rect(along, along)
    return (x0, y0), (x1, y1)


def _holds(rect: Rect, point: tuple[float, float]) -> bool:
    x0, y0, x1, y1 = rect
    x, y = point
    tol = JOIN_TOLERANCE
    return x0 - tol <= x <= x1 + tol and y0 - tol <= y <= y1 + tol


# ---------------------------------------------------------------------------------------------- the building


def load_building(path: str | Path, *, resolution: float = 0.05, seed: int | None = None) -> Building:
    """Load a building from its directory (or its building.yaml); ``scene_id`` is the directory's name.

    Every storey's plan is read as a map scene's (:func:`~drivenav.envs.embedded.rosmap.read_map_plan`); a plan
    without objects gets them placed with :func:`~drivenav.envs.embedded.rosmap.scene_rng` of the building's id and
    the storey's index, and ``seed``.
    """
    yaml_path = find_building_yaml(path)
    if yaml_path is None:
        raise InputError(path, "path", f"a building directory (holding {BUILDING_FILE}) or its {BUILDING_FILE}")
    spec = read_building_yaml(yaml_path)
    plans = [read_map_plan(storey.plan, resolution) for storey in spec.storeys]
    _check_one_grid(plans)
    scene_id = spec.scene_id
    bare = Building(
        scene_id,
        tuple(Storey(_plan_scene(scene_id, plan), s.elevation) for plan, s in zip(plans, spec.storeys, strict=True)),
        spec.stairs,
        source=str(spec.path),
    )
    fields = Fields(spec.path)
    for i, stair in enumerate(bare.stairs):
        _check_stair_floors(fields, f"stairs[{i}]", bare, stair)
    return _furnish(bare, plans, seed)


def _plan_scene(scene_id: str, plan: MapPlan) -> Scene:
    """A storey's plan without its objects (placed or checked once the stairs are known)."""
    return Scene(scene_id, plan.grid, plan.structure, rooms=list(plan.rooms), source=str(plan.yaml))


def _check_one_grid(plans: list[MapPlan]) -> None:
    """Every storey's map gives the grid of the ground floor's (the storeys are stacked cell over cell)."""
    first = plans[0].grid
    for plan in plans[1:]:
        if plan.grid.origin != first.origin:
            expected = f"{list(first.origin)}, the origin of storeys[0]'s map: a building's plans share one grid"
            raise InputError(plan.yaml, "origin", expected, list(plan.grid.origin))
        if plan.grid.shape != first.shape:
            expected = f"a map of {_size(first)} as storeys[0]'s: a building's plans share one grid"
            raise InputError(plan.yaml, "image", expected, _size(plan.grid))


def _size(grid: GridSpec) -> str:
    xmin, xmax, ymin, ymax = grid.extent
    rows, cols = grid.shape
    return f"{xmax - xmin:g} x {ymax - ymin:g} m ({cols} x {rows} cells of {grid.resolution:g} m)"


def _check_stair_floors(fields: Fields, name: str, building: Building, stair: Staircase) -> None:
    """The stairs stand on free floor of their storey, and lead from free floor there to free floor above."""
    lower, upper = stair.lower, stair.lower + 1
    below, above = _free_floor(building, lower), _free_floor(building, upper)
    parts = [(f"{name}.flights[{k}]", f.rect()) for k, f in enumerate(stair.flights)]
    parts += [(f"{name}.landings[{k}].rect", landing.rect) for k, landing in enumerate(stair.landings)]
    for field, rect in parts:
        problem = _off_floor(building.grid, below, rect)
        if problem is not None:
            raise fields.error(field, f"stairs over free floor of storeys[{lower}] (at {_rect_text(rect)})", problem)
    approach, arrival = stair.ends(ARRIVAL_DEPTH)
    problem = _off_floor(building.grid, below, approach)
    if problem is not None:
        where = f"{ARRIVAL_DEPTH:g} m before the first riser ({_rect_text(approach)})"
        raise fields.error(f"{name}.flights[0].foot", f"free floor of storeys[{lower}] for {where}", problem)
    problem = _off_floor(building.grid, above, arrival)
    if problem is not None:
        where = f"{ARRIVAL_DEPTH:g} m beyond the top edge of the stairs ({_rect_text(arrival)})"
        last = f"{name}.flights[{len(stair.flights) - 1}]"
        raise fields.error(last, f"free floor of storeys[{upper}] for {where}", problem)


def _free_floor(building: Building, j: int) -> NDArray[np.bool_]:
    """Storey ``j``'s free cells that are not open to the storey below."""
    floor: NDArray[np.bool_] = (building.storeys[j].plan.structure == Material.FREE) & ~building.holes[j]
    return floor


def _off_floor(grid: GridSpec, floor: NDArray[np.bool_], rect: Rect) -> str | None:
    """What keeps ``rect`` off ``floor`` (None: nothing): leaving the map, or cells that are not floor."""
    xmin, xmax, ymin, ymax = grid.extent
    x0, y0, x1, y1 = rect
    if x0 < xmin - _EPS or y0 < ymin - _EPS or x1 > xmax + _EPS or y1 > ymax + _EPS:
        return f"a rectangle off the map (x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}])"
    cells = rect_cells(grid, rect)
    bad = int((cells & ~floor).sum())
    return None if bad == 0 else f"{bad} of its {int(cells.sum())} cells wall, unknown space or stairwell"


def _rect_text(rect: Rect) -> str:
    """A rectangle as building.yaml writes one, to the millimetre."""
    return "[" + ", ".join(f"{round(v, 3):g}" for v in rect) + "]"


# ------------------------------------------------------------------------------------------------- objects


def _furnish(bare: Building, plans: list[MapPlan], seed: int | None) -> Building:
    """Every storey with its objects (an objects.json's, checked off the stairs and stairwells, or placed clear of
    them), instance ids numbered through the building, and its ceiling under the next slab."""
    storeys: list[Storey] = []
    first_id = 0
    for j, (storey, plan) in enumerate(zip(bare.storeys, plans, strict=True)):
        objects = _storey_objects(bare, j, plan, seed)
        objects = [replace(obj, instance_id=obj.instance_id + first_id) for obj in objects]
        first_id += len(objects)
        below_slab = j + 1 < len(bare.storeys)
        ceiling = bare.ceiling(j) - storey.elevation if below_slab else storey.plan.ceiling_height
        storeys.append(Storey(replace(storey.plan, objects=objects, ceiling_height=ceiling), storey.elevation))
    return replace(bare, storeys=tuple(storeys))


def _storey_objects(bare: Building, j: int, plan: MapPlan, seed: int | None) -> list[ObjectInstance]:
    if plan.objects is not None:
        _check_objects_clear(bare, j, plan.objects, plan.yaml.parent / OBJECTS_FILE)
        return plan.objects
    no_floor = bare.stair_cells[j] | bare.holes[j] | box_cells(bare.grid, bare.railings[j])
    scene = bare.storeys[j].plan
    masked = replace(scene, structure=np.where(no_floor, np.uint8(Material.WALL), scene.structure))
    rng = scene_rng(f"{bare.scene_id}/storeys[{j}]", seed)
    return place_objects(masked, rng, keep_clear=stair_ends(bare, j, CLEAR_DEPTH))


def _check_objects_clear(bare: Building, j: int, objects: list[ObjectInstance], source: Path) -> None:
    """No object of storey ``j``'s objects.json stands over its stairwells or on the stairs rising from it."""
    fields = Fields(source)
    for k, obj in enumerate(objects):
        if _covers(bare.grid, obj, bare.holes[j]):
            expected = f"an object off storeys[{j}]'s stairwells (its floor is open over the stairs below)"
            raise fields.error(f"objects[{k}]", expected, f"a footprint over a stairwell at {list(obj.center)}")
        if _covers(bare.grid, obj, bare.stair_cells[j]):
            expected = f"an object off the stairs rising from storeys[{j}]"
            raise fields.error(f"objects[{k}]", expected, f"a footprint on the stairs at {list(obj.center)}")


def _covers(grid: GridSpec, obj: ObjectInstance, cells: NDArray[np.bool_]) -> bool:
    """Whether the object's footprint (the cell of its centre, and the cells whose centres it holds) meets
    ``cells``."""
    block = grid.block_covering(obj.footprint())
    row, col = grid.cell_at(*obj.center)
    return bool(cells[row, col] or (cells[block] & obj.contains(*grid.cell_centers(*block))).any())
