"""Procedural houses: determinism, room counts and areas, walls, doors, corridors with junctions, connectivity."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.envs.embedded.procedural import HALLWAY, MAX_ROOMS, generate_house
from drivenav.envs.embedded.scene import Material, Scene
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError

SEEDS = range(30)
RES = 0.05


@cache
def house(seed: int, num_rooms: int | None = None) -> Scene:
    return generate_house(seed, num_rooms)


def proper_rooms(scene: Scene) -> list[str]:
    return [room.name for room in scene.rooms if room.name != HALLWAY]


def run_lengths(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Per cell: how many consecutive mask cells start there going towards +col."""
    runs = np.zeros(mask.shape, dtype=np.int64)
    for j in range(mask.shape[1] - 1, -1, -1):
        after = runs[:, j + 1] if j + 1 < mask.shape[1] else 0
        runs[:, j] = (after + 1) * mask[:, j]
    return runs


def junction_cells(scene: Scene, arm: float = 2.0) -> NDArray[np.bool_]:
    """Corridor cells from which at least three of the four axis directions run ``arm`` metres in corridor.

    A straight corridor (at most 1.8 m wide) or a bend offers two such directions; a T-junction three and a
    crossing four.
    """
    hall_ids = [k + 1 for k, room in enumerate(scene.rooms) if room.name == HALLWAY]
    hall = np.isin(scene.room_index, hall_ids)
    need = round(arm / scene.grid.resolution)
    arms = [
        run_lengths(hall),
        run_lengths(hall[:, ::-1])[:, ::-1],
        run_lengths(hall.T).T,
        run_lengths(hall.T[:, ::-1])[:, ::-1].T,
    ]
    result: NDArray[np.bool_] = sum((a >= need).astype(np.int64) for a in arms) >= 3
    return result


def test_same_seed_same_house() -> None:
    a, b = generate_house(7), generate_house(7)
    assert a.scene_id == b.scene_id == "procedural/house_00007"
    assert np.array_equal(a.structure, b.structure)
    assert a.grid == b.grid
    assert a.rooms == b.rooms
    assert a.objects == b.objects


def test_different_seeds_differ() -> None:
    assert house(1).rooms != house(2).rooms


def test_drawn_room_count_matches_explicit_request() -> None:
    for seed in (3, 4):
        drawn = len(proper_rooms(house(seed)))
        explicit = generate_house(seed, num_rooms=drawn)
        assert np.array_equal(explicit.structure, house(seed).structure)
        assert explicit.objects == house(seed).objects


@pytest.mark.parametrize("n", range(1, MAX_ROOMS + 1))
def test_requested_room_count(n: int) -> None:
    scene = house(100 + n, n)
    assert len(proper_rooms(scene)) == n
    assert all(room.name in VOCABULARY.room_types for room in scene.rooms)


def test_drawn_room_counts_span_the_range() -> None:
    counts = [len(proper_rooms(house(seed))) for seed in SEEDS]
    assert min(counts) >= 1 and max(counts) <= MAX_ROOMS
    assert len(set(counts)) >= 8


@pytest.mark.parametrize("seed", SEEDS)
def test_house_area_walls_and_outside(seed: int) -> None:
    scene = house(seed)
    structure = scene.structure
    footprint = (structure != Material.UNKNOWN).sum() * RES**2
    assert 40.0 <= footprint <= 400.0
    border = np.concatenate([structure[0], structure[-1], structure[:, 0], structure[:, -1]])
    assert np.all(border == Material.UNKNOWN)
    # Sealed: free space never touches the outside.
    outside = ndimage.binary_dilation(structure == Material.UNKNOWN)
    assert not np.any(outside & (structure == Material.FREE))
    # Walls 2-3 cells (0.10-0.15 m) thick: the outer wall seen along rows (mostly crossing it at right angles).
    rows = [row for row in structure if np.any(row == Material.FREE)]
    thickness = [np.argmax(row == Material.FREE) - np.argmax(row != Material.UNKNOWN) for row in rows]
    assert min(thickness) >= 2
    assert 2 <= np.median(thickness) <= 3


@pytest.mark.parametrize("seed", SEEDS)
def test_rooms_are_free_named_and_reachable(seed: int) -> None:
    scene = house(seed)
    index = scene.room_index
    assert np.all(scene.structure[index > 0] == Material.FREE)
    labels, count = ndimage.label(scene.navigable_grid(0.18, 0.88))
    assert count == 1
    for k, room in enumerate(scene.rooms):
        in_room = labels[index == k + 1]
        assert np.any(in_room == 1), f"{room.name} #{k} has no navigable cell"


def test_every_room_type_appears_somewhere() -> None:
    seen = {room.name for seed in SEEDS for room in house(seed).rooms}
    assert seen == set(VOCABULARY.room_types)


@pytest.mark.parametrize("seed", SEEDS)
def test_corridors_are_1_2_to_1_8_m_wide(seed: int) -> None:
    for room in house(seed).rooms:
        if room.name == HALLWAY:
            xs, ys = zip(*room.polygon, strict=True)
            narrow = min(max(xs) - min(xs), max(ys) - min(ys))
            assert 1.2 - 0.15 <= narrow <= 1.8 - 0.1 + 1e-9  # centre-line width less one wall thickness


@pytest.mark.parametrize("seed", SEEDS)
def test_houses_of_five_rooms_or_more_have_a_corridor_junction(seed: int) -> None:
    scene = house(seed)
    if len(proper_rooms(scene)) >= 5:
        assert junction_cells(scene).any()


def test_junction_detector_rejects_a_plain_corridor() -> None:
    scene = house(100 + 4, 4)
    hall_ids = [k + 1 for k, room in enumerate(scene.rooms) if room.name == HALLWAY]
    straight = Scene(scene.scene_id, scene.grid, scene.structure, rooms=[scene.rooms[hall_ids[0] - 1]])
    assert not junction_cells(straight).any()


def door_widths(scene: Scene) -> list[float]:
    """Width of every door: the free gap, outside every room, between two aligned door-frame jambs (metres)."""
    structure = scene.structure
    outside_rooms = scene.room_index == 0
    labels, _ = ndimage.label(structure == Material.DOOR_FRAME)
    boxes = ndimage.find_objects(labels)
    widths = []
    for ra, ca in boxes:
        for rb, cb in boxes:
            if ca == cb and rb.start > ra.stop:  # jambs of a door in a vertical wall
                gap, cells = (slice(ra.stop, rb.start), ca), rb.start - ra.stop
            elif ra == rb and cb.start > ca.stop:  # in a horizontal wall
                gap, cells = (ra, slice(ca.stop, cb.start)), cb.start - ca.stop
            else:
                continue
            if np.all(structure[gap] == Material.FREE) and np.all(outside_rooms[gap]):
                widths.append(cells * RES)
    return widths


@pytest.mark.parametrize("seed", SEEDS)
def test_doors_are_framed_and_0_8_to_1_1_m_wide(seed: int) -> None:
    scene = house(seed)
    n_rooms = len(proper_rooms(scene))
    widths = door_widths(scene)
    if n_rooms > 1:
        assert len(widths) >= n_rooms - 1
    assert all(0.8 - 1e-9 <= w <= 1.1 + 1e-9 for w in widths), widths
    # Every door-frame cell belongs to a jamb of a door (two jambs per door, each 2 cells along the wall).
    assert (scene.structure == Material.DOOR_FRAME).sum() <= len(widths) * 2 * 2 * 3


@pytest.mark.parametrize("seed", [5, 11])
def test_coarser_resolution_still_connected(seed: int) -> None:
    scene = generate_house(seed, resolution=0.1)
    assert scene.grid.resolution == 0.1
    assert ndimage.label(scene.navigable_grid(0.18, 0.88))[1] == 1


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"num_rooms": 0}, "num_rooms"), ({"num_rooms": 16}, "num_rooms"), ({"resolution": 0.5}, "resolution")],
)
def test_bad_arguments(kwargs: dict[str, float], field: str) -> None:
    with pytest.raises(InputError) as info:
        generate_house(1, **kwargs)  # type: ignore[arg-type]
    assert info.value.field == field
