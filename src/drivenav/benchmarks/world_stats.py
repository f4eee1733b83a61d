"""World and episode statistics of an episodes file over its scenes (``drivenav episodes stats``).

Per scene set (procedural houses, homes, floor plans: the part of the scene id before ``/``): rooms per scene, doors
per room and per room type, junction degree, loops, navigable area, storeys; per episode set: the start-to-goal
geodesic distance and the geodesic / Euclidean ratio, with their histograms, and the shares of episodes in buildings
of several storeys and of episodes that need a floor change. The methods are docs/world-vs-hm3d.md's ("How the v1
figures were computed"); the topology is :mod:`drivenav.benchmarks.floor_topology`. Navigable area is measured for
HM3D's agent (radius 0.1 m, height 1.5 m: the HM3D paper's navigable-area figure, Ramakrishnan et al. 2021,
``scale_comparison/metrics.py``) and for drivenav's own (:class:`SimConfig`).

A building (:class:`~drivenav.envs.embedded.building.Building`) is measured storey by storey and its figures added
up: each storey's floor plan gives rooms, doors, loops and regions over its own floor (the stairwell, where its slab
is open, cut out), and the building's terrain (:mod:`drivenav.envs.embedded.terrain`) gives the reachable area of
every storey and flight. Distances run up and down the stairs.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from drivenav.benchmarks.floor_topology import (
    SegmentationConfig,
    enclosed_islands,
    room_graph,
    segment_regions,
    wall_free_floor,
)
from drivenav.envs.embedded.building import Building, storeys_of
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import Scene
from drivenav.envs.embedded.terrain import Terrain, terrain_of
from drivenav.episode import HALF_STOREY, Episode
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.types import SimConfig

PLANS = "floor plans"  # the set of scenes whose ids have no "/" (map directories)
ALL = "all"


@dataclass(frozen=True)
class StatsConfig:
    """What ``episodes stats`` measures.

    - ``hm3d_radius`` / ``hm3d_height``: HM3D's navigable-area agent, 0.1 m / 1.5 m (HM3D, ``metrics.py``).
    - ``corridors``: room types counted as corridors, not rooms (rooms per scene, doors per room), as in
      docs/world-vs-hm3d.md; they stay nodes of the room graph and rows of the per-type table.
    - ``room_island_extent`` / ``plan_island_extent``: the smallest enclosed obstacle island counted as a loop,
      1 m in scenes with room labels (it then equals the room graph's loops in all 40 v1 houses) and 3 m in floor
      plans, whose scanned clutter also makes islands (an upper bound).
    - ``distance_edges`` (metres) and ``ratio_edges``: histogram bins, ``[a, b)``, the last one open.
    - ``long_episode``: 10 m, the paper's Table II threshold for long episodes.
    - ``straight_ratios``: 1.05, HM3D-OVON's generator's lowest ratio, and 1.2, below which it thins episodes out.
    - ``half_storey``: an episode without ``info.cross_floor`` needs a floor change when none of its view points
      lies within this many metres of its start's height (:func:`needs_floor_change`): 1.2 m, half of 2.4 m, the
      lowest floor-to-floor height the embedded world's buildings assume (``levels.SURFACE_BAND``'s premise; the
      ``storeys`` homes' floors are 2.8-3.2 m apart), so a view point one floor up or down is never within it, and
      one on the start's floor (a few steps above or below at most) is.
    """

    hm3d_radius: float = 0.1
    hm3d_height: float = 1.5
    corridors: tuple[str, ...] = ("hallway",)
    room_island_extent: float = 1.0
    plan_island_extent: float = 3.0
    distance_edges: tuple[float, ...] = (0.0, 2.5, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, math.inf)
    ratio_edges: tuple[float, ...] = (0.0, 1.05, 1.1, 1.2, 1.5, 2.0, 3.0, math.inf)
    long_episode: float = 10.0
    straight_ratios: tuple[float, ...] = (1.05, 1.2)
    half_storey: float = HALF_STOREY
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    sim: SimConfig = field(default_factory=SimConfig)


# -- results -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Summary:
    """A sample's size, mean, median, 90th percentile (numpy's linear) and range."""

    count: int
    mean: float
    median: float
    p90: float
    minimum: float
    maximum: float

    @classmethod
    def maybe(cls, values: Sequence[float]) -> Summary | None:
        """The summary of ``values``; None for an empty sample."""
        return cls.of(values) if len(values) else None

    @classmethod
    def of(cls, values: Sequence[float]) -> Summary:
        """The summary of a non-empty sample."""
        if not len(values):
            raise ValueError("an empty sample has no summary")
        data = np.asarray(values, dtype=np.float64)
        return cls(
            len(data),
            float(data.mean()),
            float(np.median(data)),
            float(np.percentile(data, 90)),
            float(data.min()),
            float(data.max()),
        )


@dataclass(frozen=True)
class Share:
    """``count`` of ``total`` items; ``share`` their fraction (0 for none)."""

    count: int
    total: int

    @property
    def share(self) -> float:
        return self.count / self.total if self.total else 0.0

    @classmethod
    def where(cls, flags: Sequence[bool]) -> Share:
        return cls(sum(bool(f) for f in flags), len(flags))


@dataclass(frozen=True)
class DegreeSummary:
    """Doors (or neighbours) per node: the summary and the nodes with one, two and three or more."""

    summary: Summary
    one: Share
    two: Share
    three_or_more: Share

    @classmethod
    def of(cls, degrees: Sequence[int]) -> DegreeSummary | None:
        if not degrees:
            return None
        return cls(
            Summary.of([float(d) for d in degrees]),
            Share.where([d == 1 for d in degrees]),
            Share.where([d == 2 for d in degrees]),
            Share.where([d >= 3 for d in degrees]),
        )


@dataclass(frozen=True)
class Histogram:
    """Counts per bin ``[edges[k], edges[k + 1])``."""

    edges: tuple[float, ...]
    counts: tuple[int, ...]

    @classmethod
    def of(cls, values: Sequence[float], edges: tuple[float, ...]) -> Histogram:
        bins = np.searchsorted(np.asarray(edges), np.asarray(values, dtype=np.float64), side="right") - 1
        counts = np.bincount(bins[(bins >= 0) & (bins < len(edges) - 1)], minlength=len(edges) - 1)
        return cls(edges, tuple(int(c) for c in counts))


@dataclass(frozen=True)
class SceneStats:
    """One scene's figures (a building's: its storeys' together). Room-graph figures are None for a scene without
    room labels."""

    scene_id: str
    scene_set: str
    area_hm3d: float
    area_agent: float
    rooms: int | None
    corridors: int | None
    room_types: tuple[str, ...]
    doors: tuple[int, ...]
    room_loops: int | None
    islands: int
    island_extent: float
    region_degrees: tuple[int, ...]
    storeys: int


@dataclass(frozen=True)
class EpisodeStats:
    """One episode's start-to-goal geodesic distance and its ratio to the straight line (NaN without one), whether
    its scene has several storeys and whether it needs a floor change."""

    episode_id: str
    scene_set: str
    geodesic: float
    ratio: float
    multi_storey: bool
    floor_change: bool


@dataclass(frozen=True)
class LoopSummary:
    """Loops per scene: the scenes with at least one, and the mean, median and largest count."""

    scenes_with_loop: Share
    mean: float
    median: float
    maximum: int

    @classmethod
    def of(cls, loops: Sequence[int]) -> LoopSummary | None:
        if not loops:
            return None
        return cls(Share.where([n > 0 for n in loops]), float(np.mean(loops)), float(np.median(loops)), max(loops))


@dataclass(frozen=True)
class SceneSetStats:
    """A scene set's figures; room-graph ones over its scenes with room labels (None if it has none)."""

    name: str
    scenes: int
    rooms_per_scene: Summary | None
    corridors_per_scene: Summary | None
    doors_per_room: DegreeSummary | None
    doors_by_type: dict[str, DegreeSummary]
    junction_degree: DegreeSummary | None
    room_graph_loops: LoopSummary | None
    island_loops: LoopSummary
    regions_per_scene: Summary
    region_degree: DegreeSummary | None
    area_hm3d: Summary
    area_agent: Summary
    storeys_per_scene: dict[str, Share]


@dataclass(frozen=True)
class EpisodeSetStats:
    """An episode set's distances (metres), geodesic / Euclidean ratios, and the episodes in scenes of several
    storeys and those that need a floor change."""

    name: str
    episodes: int
    geodesic: Summary
    geodesic_histogram: Histogram
    over_long: Share
    ratio: Summary | None
    ratio_histogram: Histogram
    ratio_below: dict[str, Share]
    in_multi_storey_scenes: Share
    floor_change: Share


@dataclass(frozen=True)
class WorldStats:
    """Everything ``episodes stats`` prints: per scene set, per episode set, and per scene."""

    config: StatsConfig
    scene_sets: tuple[SceneSetStats, ...]
    episode_sets: tuple[EpisodeSetStats, ...]
    scenes: tuple[SceneStats, ...]

    def to_json(self) -> JsonObject:
        """The figures as JSON (shares as ``{"count", "total", "share"}``; infinite bin edges as null)."""
        data = _finite(asdict(self))
        assert isinstance(data, dict)
        return data


def _finite(value: object) -> object:
    """``asdict``'s output made strict JSON: infinities and NaN as null, tuples as lists, shares with their
    fraction."""
    if isinstance(value, dict):
        out = {str(k): _finite(v) for k, v in value.items()}
        if set(out) == {"count", "total"} and isinstance(out["total"], int) and isinstance(out["count"], int):
            out["share"] = Share(out["count"], out["total"]).share
        return out
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# -- measuring -----------------------------------------------------------------------------------------------


def scene_set(scene_id: str) -> str:
    """The set a scene belongs to: its id's prefix (``procedural``, ``homes``), else :data:`PLANS`."""
    return scene_id.split("/", 1)[0] if "/" in scene_id else PLANS


def measure_scene(
    scene: Scene | Building, config: StatsConfig = StatsConfig(), terrain: Terrain | None = None
) -> SceneStats:
    """One scene's or building's figures (docs/world-vs-hm3d.md's methods; a building's storeys added up, see the
    module's docstring). Staircases are no doors of the room graph, so a pair of storeys joined by one staircase (as
    in every ``storeys`` home) adds no loop. ``terrain``: the scene's for drivenav's agent, if already built."""
    terrain = terrain or terrain_of(scene, config.sim)
    hm3d = terrain_of(scene, replace(config.sim, agent_radius=config.hm3d_radius, agent_height=config.hm3d_height))
    res = terrain.grid.resolution
    floors = storey_floors(scene, terrain)
    labelled = any(plan.rooms for plan, _ in floors)
    extent = config.room_island_extent if labelled else config.plan_island_extent
    graphs = [room_graph(plan, floor) for plan, floor in floors if plan.rooms]
    corridors = sum(room.name in config.corridors for plan, _ in floors for room in plan.rooms)
    rooms = sum(len(plan.rooms) for plan, _ in floors) - corridors
    return SceneStats(
        scene_id=scene.scene_id,
        scene_set=scene_set(scene.scene_id),
        area_hm3d=float(hm3d.reachable.sum()) * res * res,
        area_agent=float(terrain.reachable.sum()) * res * res,
        rooms=rooms if labelled else None,
        corridors=corridors if labelled else None,
        room_types=tuple(name for graph in graphs for name in graph.names),
        doors=tuple(doors for graph in graphs for doors in graph.degrees),
        room_loops=sum(graph.loops for graph in graphs) if labelled else None,
        islands=sum(enclosed_islands(floor, res, extent) for _, floor in floors),
        island_extent=extent,
        region_degrees=tuple(
            d for _, floor in floors for d in segment_regions(floor, res, config.segmentation).degrees
        ),
        storeys=len(floors),
    )


def storey_floors(scene: Scene | Building, terrain: Terrain) -> list[tuple[Scene, NDArray[np.bool_]]]:
    """Each storey's floor plan and its floor (:func:`wall_free_floor` around the storey's part of the terrain's
    reachable area, with the stairs that rise from it and, in a building, without its stairwells): a one-floor
    scene's is its own."""
    holes = scene.holes if isinstance(scene, Building) else (None,)
    return [
        (storey.plan, wall_free_floor(storey.plan, terrain.reachable[j], holes[j]))
        for j, storey in enumerate(storeys_of(scene))
    ]


def needs_floor_change(episode: Episode, half_storey: float) -> bool:
    """Whether no goal of the episode lies on its start's floor: ``info.cross_floor`` where the episode has it
    (drivenav's episodes in buildings of several storeys), else whether none of its view points lies within
    ``half_storey`` metres of the start's height (HM3D's files carry no floor information; a goal is on the start's
    floor when one of its view points is)."""
    given = episode.info.get("cross_floor")
    if isinstance(given, bool):
        return given
    return all(abs(height - episode.start_height) > half_storey for *_, height in episode.view_points_xyz())


Distance = Callable[[float, float, float], float]
"""Geodesic distance from an episode's start to a world point of some height (``inf``: no path)."""


def terrain_distances(episode: Episode, terrain: Terrain) -> tuple[float, float]:
    """:func:`distances_from_start` over a scene's or building's terrain (in a building, up and down the stairs)."""
    return distances_from_start(episode, terrain.field([(*episode.start_xy, episode.start_height)]).at)


def distances_from_start(episode: Episode, from_start: Distance) -> tuple[float, float]:
    """The episode's start-to-goal geodesic distance (``info.geodesic_distance``, else measured here) and its ratio to
    the straight line from the start to the geodesically nearest view point (heights included), found by one
    fast-marching solve from the start (``from_start``): the quantity HM3D-OVON's generator filters on. The ratio is
    NaN if no view point is reachable or the line has no length."""
    points = episode.view_points_xyz()
    distances = [from_start(*point) for point in points]
    nearest = int(np.argmin(distances)) if distances else -1
    if nearest < 0 or not math.isfinite(distances[nearest]):
        return episode.geodesic_distance, math.nan
    given = episode.geodesic_distance
    geodesic = given if math.isfinite(given) else distances[nearest]
    line = math.dist((*episode.start_xy, episode.start_height), points[nearest])
    return geodesic, geodesic / line if line > 0.0 else math.nan


def measure(
    episodes: Sequence[Episode],
    library: SceneLibrary,
    config: StatsConfig = StatsConfig(),
    source: str = "EPISODES",
    measured_one: Callable[[], object] = lambda: None,
) -> WorldStats:
    """The statistics of ``episodes`` and of the scenes they use (each scene once, in first-use order), loaded from
    ``library``; an episode whose scene ``library`` lacks is an :class:`InputError` naming ``source``.
    ``measured_one`` is called after each episode is measured (a progress bar's step: an episode's distances take
    milliseconds, a million of them many minutes)."""
    by_scene: dict[str, list[Episode]] = {}
    for i, episode in enumerate(episodes):
        if episode.scene_id not in library:
            expected = f"a scene of --scenes {library.spec}"
            raise InputError(source, f"episodes[{i}].scene_id", expected, episode.scene_id)
        by_scene.setdefault(episode.scene_id, []).append(episode)
    scenes: list[SceneStats] = []
    measured: list[EpisodeStats] = []
    for scene_id, scene_episodes in by_scene.items():
        scene = library.load(scene_id)
        terrain = terrain_of(scene, config.sim)
        scenes.append(measure_scene(scene, config, terrain))
        for episode in scene_episodes:
            measured.append(_episode_stats(episode, scenes[-1], terrain, config))
            measured_one()
    names = list(dict.fromkeys(s.scene_set for s in scenes))
    groups = [*names, ALL] if len(names) > 1 else names
    return WorldStats(
        config=config,
        scene_sets=tuple(_scene_set_stats(g, [s for s in scenes if g in (ALL, s.scene_set)], config) for g in groups),
        episode_sets=tuple(
            _episode_set_stats(g, [e for e in measured if g in (ALL, e.scene_set)], config) for g in groups
        ),
        scenes=tuple(scenes),
    )


def _episode_stats(episode: Episode, scene: SceneStats, terrain: Terrain, config: StatsConfig) -> EpisodeStats:
    geodesic, ratio = terrain_distances(episode, terrain)
    floor_change = needs_floor_change(episode, config.half_storey)
    return EpisodeStats(episode.episode_id, scene.scene_set, geodesic, ratio, scene.storeys > 1, floor_change)


def _scene_set_stats(name: str, scenes: list[SceneStats], config: StatsConfig) -> SceneSetStats:
    labelled = [s for s in scenes if s.rooms is not None]
    rooms = [(kind, doors) for s in labelled for kind, doors in zip(s.room_types, s.doors, strict=True)]
    by_type: dict[str, list[int]] = {}
    for kind, doors in sorted(rooms, key=lambda r: r[0]):
        by_type.setdefault(kind, []).append(doors)
    doors_by_type = {k: d for k, v in by_type.items() if (d := DegreeSummary.of(v)) is not None}
    islands = LoopSummary.of([s.islands for s in scenes])
    assert islands is not None  # a set has at least one scene
    return SceneSetStats(
        name=name,
        scenes=len(scenes),
        rooms_per_scene=Summary.maybe([float(s.rooms or 0) for s in labelled]),
        corridors_per_scene=Summary.maybe([float(s.corridors or 0) for s in labelled]),
        doors_per_room=DegreeSummary.of([d for kind, d in rooms if kind not in config.corridors]),
        doors_by_type=dict(sorted(doors_by_type.items(), key=lambda kv: (-kv[1].summary.count, kv[0]))),
        junction_degree=DegreeSummary.of([d for _, d in rooms]),
        room_graph_loops=LoopSummary.of([s.room_loops or 0 for s in labelled]),
        island_loops=islands,
        regions_per_scene=Summary.of([float(len(s.region_degrees)) for s in scenes]),
        region_degree=DegreeSummary.of([d for s in scenes for d in s.region_degrees]),
        area_hm3d=Summary.of([s.area_hm3d for s in scenes]),
        area_agent=Summary.of([s.area_agent for s in scenes]),
        storeys_per_scene=_storeys_per_scene([s.storeys for s in scenes]),
    )


def _storeys_per_scene(storeys: Sequence[int]) -> dict[str, Share]:
    """The scenes of each number of storeys (keys ``"1"``, ``"2"``, ... in increasing order)."""
    counts = Counter(storeys)
    return {str(n): Share(counts[n], len(storeys)) for n in sorted(counts)}


def _episode_set_stats(name: str, episodes: list[EpisodeStats], config: StatsConfig) -> EpisodeSetStats:
    distances = [e.geodesic for e in episodes]
    ratios = [e.ratio for e in episodes if math.isfinite(e.ratio)]
    return EpisodeSetStats(
        name=name,
        episodes=len(episodes),
        geodesic=Summary.of(distances),
        geodesic_histogram=Histogram.of(distances, config.distance_edges),
        over_long=Share.where([d > config.long_episode for d in distances]),
        ratio=Summary.maybe(ratios),
        ratio_histogram=Histogram.of(ratios, config.ratio_edges),
        ratio_below={f"{limit:g}": Share.where([r < limit for r in ratios]) for limit in config.straight_ratios},
        in_multi_storey_scenes=Share.where([e.multi_storey for e in episodes]),
        floor_change=Share.where([e.floor_change for e in episodes]),
    )
