"""Door rules of the home generator (:mod:`drivenav.envs.embedded.homes`): which neighbouring rooms get a door.

Modelled on ProcTHOR's door rules (allenai/procthor, ``procthor/generation/doors.py``): kitchen and living room
may be joined by an open connection without a wall (``OPEN_ROOM_CONNECTIONS``), and bathrooms avoid doors from
outside their suite (``avoid_doors_from_metarooms``), so an ensuite bathroom opens into its bedroom. Beyond a
connected set of doors, real homes have loops: a bathroom between the hall and a bedroom with a door to each
(a "Jack and Jill" bathroom), a corner room opening onto two halls, a kitchen - laundry - garage chain, a living
room opening into the family room or study. Each of those is a rule with its own probability here.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.procedural import CellBox, Edge, Raster, door_capacity, shared_edge
from drivenav.envs.embedded.scene import Material

_SERVICE = (
    frozenset({"kitchen", "laundry room"}),
    frozenset({"laundry room", "garage"}),
    frozenset({"kitchen", "garage"}),
)
_FAMILY = frozenset({"office", "playroom", "living room"})
_SUITE = ("bathroom", "closet")  # rooms that may open only into a neighbouring bedroom


@dataclass(frozen=True)
class DoorRules:
    """Probabilities of the door rules and the width of open-plan openings.

    ``open_width``: metres of wall removed between open-plan rooms (about a wide cased opening to a wall
    removed; never the whole wall, so each opening stays one gap between two rooms). ``p_core_open_to_hall``:
    an open-plan room opens onto the hall with such an opening instead of a door. ``p_ensuite``: a bathroom or
    closet next to a bedroom opens only into it, not onto the hall. ``p_jack_and_jill``: a bathroom with a hall
    door also opens into a neighbouring bedroom. ``p_second_hall``: a room touching two halls opens onto both.
    ``p_service``: kitchen - laundry, laundry - garage and kitchen - garage doors. ``p_family``: a living room
    opens into a neighbouring family room, study or playroom.
    """

    open_width: tuple[float, float] = (1.6, 3.0)
    p_core_open_to_hall: float = 0.5
    p_ensuite: float = 0.5
    p_jack_and_jill: float = 0.5
    p_second_hall: float = 0.6
    p_service: float = 0.8
    p_family: float = 0.8


@dataclass(frozen=True)
class Door:
    """An opening between boxes ``a < b``: a door, or a wide ``open`` connection."""

    a: int
    b: int
    open: bool


class _Doors:
    """The doors chosen so far, and which boxes they connect to the halls."""

    def __init__(self, labels: list[str], n_rooms: int, pairs: dict[tuple[int, int], int]) -> None:
        self.labels = labels
        self.n_rooms = n_rooms
        self.pairs = pairs
        self.chosen: dict[tuple[int, int], bool] = {}

    def add(self, a: int, b: int, is_open: bool) -> None:
        self.chosen.setdefault((min(a, b), max(a, b)), is_open)

    def neighbours(self, box: int) -> list[int]:
        return [b if a == box else a for a, b in self.pairs if box in (a, b)]

    def halls_of(self, room: int) -> list[int]:
        return [h for h in self.neighbours(room) if h >= self.n_rooms]

    def reached(self) -> set[int]:
        """Boxes connected to the halls through chosen doors (the halls are open into each other)."""
        seen = set(range(self.n_rooms, len(self.labels)))
        todo = list(seen)
        while todo:
            box = todo.pop()
            for a, b in self.chosen:
                other = b if a == box else a if b == box else None
                if other is not None and other not in seen:
                    seen.add(other)
                    todo.append(other)
        return seen


def choose_doors(
    rng: np.random.Generator,
    rules: DoorRules,
    raster: Raster,
    boxes: list[CellBox],
    labels: list[str],
    n_rooms: int,
    core: list[int],
    walled: frozenset[int] = frozenset(),
) -> list[Door]:
    """The doors of one home. Boxes ``0..n_rooms-1`` are rooms, the rest halls; ``core`` is the open-plan row;
    ``walled`` boxes get no door (a hall strip that holds stairs).

    Every room ends up connected to the halls. Pairs whose shared wall cannot hold a door are never chosen.
    """
    pairs = {
        (a, b): door_capacity(raster, edge)
        for a in range(n_rooms)
        for b in range(a + 1, len(boxes))
        if b not in walled
        and (edge := shared_edge(boxes[a], boxes[b])) is not None
        and door_capacity(raster, edge) >= raster.min_door
    }
    doors = _Doors(labels, n_rooms, pairs)
    for a, b in pairwise(core):
        if (a, b) in pairs:
            doors.add(a, b, True)
    _hall_doors(rng, rules, doors, core)
    _reach_the_rest(rng, doors)
    _loops(rng, rules, doors)
    return [Door(a, b, is_open) for (a, b), is_open in doors.chosen.items()]


def _hall_doors(rng: np.random.Generator, rules: DoorRules, doors: _Doors, core: list[int]) -> None:
    """Each room touching a hall opens onto the one with the fewest doors so far, except ensuite rooms."""
    count = {h: 0 for h in range(doors.n_rooms, len(doors.labels))}
    for room in range(doors.n_rooms):
        halls = doors.halls_of(room)
        if not halls:
            continue
        beside_bedroom = any(doors.labels[n] == "bedroom" for n in doors.neighbours(room))
        if doors.labels[room] in _SUITE and beside_bedroom and rng.random() < rules.p_ensuite:
            continue
        hall = min(halls, key=lambda h: (count[h], h))
        count[hall] += 1
        doors.add(room, hall, room in core and rng.random() < rules.p_core_open_to_hall)


def _reach_the_rest(rng: np.random.Generator, doors: _Doors) -> None:
    """Rooms not yet connected open into a connected neighbour: a bedroom for bathrooms and closets if possible."""
    reached = doors.reached()
    while len(reached) < len(doors.labels):
        frontier = [(a, b) if b in reached else (b, a) for a, b in doors.pairs if (a in reached) != (b in reached)]
        if not frontier:
            raise RuntimeError("home plan has a room that no door can reach")
        preferred = [
            (room, via)
            for room, via in frontier
            if (doors.labels[room] in _SUITE) == (doors.labels[via] == "bedroom") and doors.labels[via] not in _SUITE
        ]
        room, via = (preferred or frontier)[int(rng.integers(len(preferred or frontier)))]
        doors.add(room, via, False)
        reached.add(room)


def _loops(rng: np.random.Generator, rules: DoorRules, doors: _Doors) -> None:
    """Second doors that close loops, by the room types on either side."""
    for a, b in sorted(doors.pairs):
        if (a, b) in doors.chosen:
            continue
        types = frozenset({doors.labels[a], doors.labels[b]})
        p = 0.0
        if types == {"bathroom", "bedroom"}:
            p = rules.p_jack_and_jill
        elif b >= doors.n_rooms and any(h != b and (a, h) in doors.chosen for h in doors.halls_of(a)):
            p = rules.p_second_hall
        elif types in _SERVICE:
            p = rules.p_service
        elif "living room" in types and types <= _FAMILY:
            p = rules.p_family
        if p > 0.0 and rng.random() < p:
            doors.add(a, b, False)


def cut_opening(
    rng: np.random.Generator,
    structure: NDArray[np.uint8],
    raster: Raster,
    edge: Edge,
    width: tuple[float, float],
) -> None:
    """Remove ``width`` metres of the wall along ``edge`` (at most its door capacity), leaving wall at both ends."""
    lo, hi = raster.interior(edge.lo, edge.hi)
    cells = int(rng.integers(round(width[0] / raster.resolution), round(width[1] / raster.resolution) + 1))
    cells = max(raster.min_door, min(cells, door_capacity(raster, edge)))
    start = int(rng.integers(lo + raster.jamb + 1, hi - raster.jamb - 1 - cells + 1))
    raster.paint(structure, edge, start, start + cells, Material.FREE)
