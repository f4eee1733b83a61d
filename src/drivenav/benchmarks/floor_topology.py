"""The topology of an embedded scene's floor: its room graph, its loops and a room segmentation for plans without
room labels.

A home's layout decides how often an explorer must choose between branches and whether it can come back by another
way. The paper's Table II (revisits, steps) is measured in HM3D homes; these figures say how far a scene set is
from being a tree. The methods are those of docs/world-vs-hm3d.md ("How the v1 figures were computed"):

- the **floor** is the wall-free floor (:attr:`Material.FREE`, furniture ignored) in the 4-connected pieces that
  hold the agent's reachable area; a building's storey has one of its own, without its stairwells;
- the **room graph** has one node per :attr:`Scene.rooms` entry; every connected group of floor cells inside no
  room polygon (a door gap) joins the rooms it touches, and rooms whose polygons touch on the floor (no wall
  between them: open-plan areas, corridors that open into each other) are joined once per pair;
- **loops** are the graph's first Betti number (connections - nodes + components), and independently the
  obstacle islands (8-connected) that the floor encloses, at least ``min_extent`` across: the floor's own first
  Betti number, which needs no room labels;
- **regions** are a morphological segmentation of the floor (seeds where the clearance exceeds ``seed_clearance``,
  regrown by a 4-neighbour wavefront), for plans without room labels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from drivenav.envs.embedded.scene import Material, Scene

EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class SegmentationConfig:
    """The morphological room segmentation (docs/world-vs-hm3d.md, "Rooms (floor plans)").

    ``seed_clearance`` 0.6 m cuts every passage narrower than 1.2 m (a door, a narrow corridor); seed blobs smaller
    than ``min_seed_area`` (0.5 m^2) are dropped; two regions are neighbours if they share at least
    ``min_shared_edges`` (2) cell edges, so a corner contact is no passage.
    """

    seed_clearance: float = 0.6
    min_seed_area: float = 0.5
    min_shared_edges: int = 2


@dataclass(frozen=True)
class RoomGraph:
    """The room graph of a scene with room labels: per node (``Scene.rooms`` order) its type and its number of
    doors and openings; ``loops`` is the graph's first Betti number."""

    names: tuple[str, ...]
    degrees: tuple[int, ...]
    loops: int


@dataclass(frozen=True)
class Regions:
    """A segmentation's regions: per region its number of neighbouring regions."""

    degrees: tuple[int, ...]


def wall_free_floor(
    scene: Scene, reachable: NDArray[np.bool_], open_slab: NDArray[np.bool_] | None = None
) -> NDArray[np.bool_]:
    """Free structure cells (furniture ignored) in the 4-connected pieces that hold a ``reachable`` cell. On a
    building's storey, ``open_slab`` marks where its slab is open (the stairwells): no floor there."""
    free = scene.structure == Material.FREE
    labels, _ = ndimage.label(free if open_slab is None else free & ~open_slab)
    kept = np.unique(labels[reachable & (labels > 0)])
    floor: NDArray[np.bool_] = np.isin(labels, kept) & (labels > 0)
    return floor


def room_graph(scene: Scene, floor: NDArray[np.bool_]) -> RoomGraph:
    """The room graph of ``scene`` over ``floor`` (see the module's docstring). A door gap that touches k rooms is
    one connection of all k (it adds k - 1 to the Betti number, like a hub node); two door gaps between the same
    two rooms are two doors, and the wall between them closes a loop."""
    index = np.where(floor, scene.room_index, -1)
    connections = _door_connections(index) + _open_joints(index)
    nodes = len(scene.rooms)
    degrees = np.zeros(nodes + 1, dtype=np.int64)
    for members in connections:
        degrees[list(members)] += 1
    return RoomGraph(
        names=tuple(room.name for room in scene.rooms),
        degrees=tuple(int(d) for d in degrees[1:]),
        loops=_betti_number(nodes, connections),
    )


def _door_connections(index: NDArray[np.int16] | NDArray[np.int64]) -> list[frozenset[int]]:
    """One connection per 4-connected group of floor cells outside every room that touches two or more rooms."""
    gaps, _ = ndimage.label(index == 0)
    connections = []
    for label, box in enumerate(ndimage.find_objects(gaps), start=1):
        if box is None:
            continue
        rows = slice(max(box[0].start - 1, 0), box[0].stop + 1)
        cols = slice(max(box[1].start - 1, 0), box[1].stop + 1)
        around = ndimage.binary_dilation(gaps[rows, cols] == label)
        touched = frozenset(int(k) for k in np.unique(index[rows, cols][around]) if k > 0)
        if len(touched) >= 2:
            connections.append(touched)
    return connections


def _open_joints(index: NDArray[np.int16] | NDArray[np.int64]) -> list[frozenset[int]]:
    """One connection per pair of rooms whose floor cells are 4-neighbours (no wall or gap between them)."""
    pairs: set[frozenset[int]] = set()
    for a, b in ((index[:, :-1], index[:, 1:]), (index[:-1], index[1:])):
        meet = (a > 0) & (b > 0) & (a != b)
        pairs.update(frozenset(p) for p in zip(a[meet].tolist(), b[meet].tolist(), strict=True))
    return sorted(pairs, key=sorted)


def _betti_number(nodes: int, connections: list[frozenset[int]]) -> int:
    """Independent cycles of a graph whose connections join two or more of ``nodes`` (1-based) rooms."""
    if nodes == 0:
        return 0
    rows = [min(c) - 1 for c in connections for _ in range(len(c) - 1)]
    cols = [k - 1 for c in connections for k in sorted(c)[1:]]
    matrix = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(nodes, nodes))
    components, _ = connected_components(matrix, directed=False)
    return len(rows) - nodes + int(components)


def enclosed_islands(floor: NDArray[np.bool_], resolution: float, min_extent: float) -> int:
    """Obstacle islands (8-connected) surrounded by ``floor``, at least ``min_extent`` metres across on their
    longer bounding-box side: the floor's loops (its first Betti number, for islands of any size)."""
    obstacles, _ = ndimage.label(np.pad(~floor, 1, constant_values=True), EIGHT_CONNECTED)
    outside = obstacles[0, 0]
    count = 0
    for label, box in enumerate(ndimage.find_objects(obstacles), start=1):
        if box is None or label == outside:
            continue
        extent = max(box[0].stop - box[0].start, box[1].stop - box[1].start) * resolution
        count += extent >= min_extent
    return count


def segment_regions(
    floor: NDArray[np.bool_], resolution: float, config: SegmentationConfig = SegmentationConfig()
) -> Regions:
    """The floor's regions and their neighbour counts (see :class:`SegmentationConfig`). Where two regions'
    wavefronts meet in one step, the higher label takes the cell."""
    rows, cols = np.nonzero(floor)
    if len(rows) == 0:
        return Regions(degrees=())
    box = (slice(max(rows.min() - 1, 0), rows.max() + 2), slice(max(cols.min() - 1, 0), cols.max() + 2))
    labels = _grown_seeds(floor[box], resolution, config)
    shared: dict[tuple[int, int], int] = {}
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1], labels[1:])):
        meet = (a > 0) & (b > 0) & (a != b)
        low, high = np.minimum(a[meet], b[meet]).tolist(), np.maximum(a[meet], b[meet]).tolist()
        for pair in zip(low, high, strict=True):
            shared[pair] = shared.get(pair, 0) + 1
    degrees = dict.fromkeys(np.unique(labels[labels > 0]).tolist(), 0)
    for (first, second), count in shared.items():
        if count >= config.min_shared_edges:
            degrees[first] += 1
            degrees[second] += 1
    return Regions(degrees=tuple(degrees.values()))


def _grown_seeds(floor: NDArray[np.bool_], resolution: float, config: SegmentationConfig) -> NDArray[np.int64]:
    cross = ndimage.generate_binary_structure(2, 1)
    clearance = ndimage.distance_transform_edt(floor) * resolution
    seeds, _ = ndimage.label(floor & (clearance > config.seed_clearance), cross)
    areas = np.bincount(seeds.ravel()) * resolution * resolution
    labels: NDArray[np.int64] = np.where((seeds > 0) & (areas[seeds] >= config.min_seed_area), seeds, 0)
    while True:
        grown = ndimage.grey_dilation(labels, footprint=cross)
        new = floor & (labels == 0) & (grown > 0)
        if not new.any():
            return labels
        labels[new] = grown[new]
