"""World and episode statistics of an episodes file over its scenes (``drivenav episodes stats``).

Per scene set (procedural houses, homes, floor plans: the part of the scene id before ``/``): rooms per scene, doors
per room and per room type, junction degree, loops, navigable area; per episode set: the start-to-goal geodesic
distance and the geodesic / Euclidean ratio, with their histograms. The methods are docs/world-vs-hm3d.md's ("How
the v1 figures were computed"); the topology is :mod:`drivenav.benchmarks.floor_topology`. Navigable area is measured
for HM3D's agent (radius 0.1 m, height 1.5 m: the HM3D paper's navigable-area figure, Ramakrishnan et al. 2021,
``scale_comparison/metrics.py``) and for drivenav's own (:class:`SimConfig`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivenav.benchmarks.floor_topology import (
    SegmentationConfig,
    enclosed_islands,
    room_graph,
    segment_regions,
    wall_free_floor,
)
from drivenav.envs.embedded.geodesic import largest_component, nearest_by_geodesic
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import Scene
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.grid import GridSpec
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
    """One scene's figures. Room-graph figures are None for a scene without room labels."""

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


@dataclass(frozen=True)
class EpisodeStats:
    """One episode's start-to-goal geodesic distance and its ratio to the straight line (NaN without one)."""

    episode_id: str
    scene_set: str
    geodesic: float
    ratio: float


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


@dataclass(frozen=True)
class EpisodeSetStats:
    """An episode set's distances (metres) and geodesic / Euclidean ratios."""

    name: str
    episodes: int
    geodesic: Summary
    geodesic_histogram: Histogram
    over_long: Share
    ratio: Summary | None
    ratio_histogram: Histogram
    ratio_below: dict[str, Share]


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


def measure_scene(scene: Scene, config: StatsConfig = StatsConfig()) -> SceneStats:
    """One scene's figures (docs/world-vs-hm3d.md's methods)."""
    sim, res = config.sim, scene.grid.resolution
    reachable = largest_component(scene.navigable_grid(sim.agent_radius, sim.agent_height))
    hm3d = largest_component(scene.navigable_grid(config.hm3d_radius, config.hm3d_height))
    floor = wall_free_floor(scene, reachable)
    extent = config.room_island_extent if scene.rooms else config.plan_island_extent
    graph = room_graph(scene, floor) if scene.rooms else None
    corridors = sum(room.name in config.corridors for room in scene.rooms)
    return SceneStats(
        scene_id=scene.scene_id,
        scene_set=scene_set(scene.scene_id),
        area_hm3d=float(hm3d.sum()) * res * res,
        area_agent=float(reachable.sum()) * res * res,
        rooms=len(scene.rooms) - corridors if graph is not None else None,
        corridors=corridors if graph is not None else None,
        room_types=graph.names if graph is not None else (),
        doors=graph.degrees if graph is not None else (),
        room_loops=graph.loops if graph is not None else None,
        islands=enclosed_islands(floor, res, extent),
        island_extent=extent,
        region_degrees=segment_regions(floor, res, config.segmentation).degrees,
    )


def start_distances(episode: Episode, reachable: NDArray[np.bool_], grid: GridSpec) -> tuple[float, float]:
    """The episode's start-to-goal geodesic distance (``info.geodesic_distance``, else measured here) and its ratio to
    the straight line from the start to the geodesically nearest view point, found by one fast-marching solve from
    the start over ``reachable``: the quantity HM3D-OVON's generator filters on. The ratio is NaN if no view point
    is reachable or the line has no length."""
    points = episode.view_points_xy()
    nearest, distance = nearest_by_geodesic(reachable, grid, episode.start_xy, points)
    if nearest < 0 or not math.isfinite(distance):
        return episode.geodesic_distance, math.nan
    given = episode.geodesic_distance
    geodesic = given if math.isfinite(given) else distance
    line = math.dist(episode.start_xy, points[nearest])
    return geodesic, geodesic / line if line > 0.0 else math.nan


def measure(
    episodes: Sequence[Episode], library: SceneLibrary, config: StatsConfig = StatsConfig(), source: str = "EPISODES"
) -> WorldStats:
    """The statistics of ``episodes`` and of the scenes they use (each scene once, in first-use order), loaded from
    ``library``; an episode whose scene ``library`` lacks is an :class:`InputError` naming ``source``."""
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
        scenes.append(measure_scene(scene, config))
        reachable = largest_component(scene.navigable_grid(config.sim.agent_radius, config.sim.agent_height))
        for episode in scene_episodes:
            geodesic, ratio = start_distances(episode, reachable, scene.grid)
            measured.append(EpisodeStats(episode.episode_id, scenes[-1].scene_set, geodesic, ratio))
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
    )


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
    )
