"""``episodes stats`` as text: one Markdown table of the scene sets' figures and one of the episode sets', one
column per set (the form of docs/world-vs-hm3d.md's figures table, so its cells can be pasted there)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TypeVar

from drivenav.benchmarks.world_stats import (
    DegreeSummary,
    EpisodeSetStats,
    Histogram,
    LoopSummary,
    SceneSetStats,
    Share,
    Summary,
    WorldStats,
)

NONE = "-"
Item = TypeVar("Item")


def format_world_stats(stats: WorldStats) -> str:
    """Both tables, each under its heading."""
    scenes, episodes = stats.scene_sets, stats.episode_sets
    parts = ["## Scenes", "", *_table([s.name for s in scenes], scenes, _scene_rows(stats))]
    parts += ["", "## Episodes", "", *_table([e.name for e in episodes], episodes, _episode_rows(stats))]
    return "\n".join(parts)


def share(value: Share) -> str:
    """``37.2 % (61 / 164)``."""
    return f"{100.0 * value.share:.1f} % ({value.count} / {value.total})"


def spread(value: Summary | None, unit: str = "") -> str:
    """``mean 8.2, median 8.5, range 1-15`` (one decimal)."""
    if value is None:
        return NONE
    return f"mean {value.mean:.1f}{unit}, median {value.median:.1f}, range {value.minimum:.1f}-{value.maximum:.1f}"


def degrees(value: DegreeSummary | None) -> str:
    """``mean 1.2, median 1; 1: 82.0 % (268 / 327), 2: ..., >= 3: ...``."""
    if value is None:
        return NONE
    head = f"mean {value.summary.mean:.1f}, median {value.summary.median:g}"
    return f"{head}; 1: {share(value.one)}, 2: {share(value.two)}, >= 3: {share(value.three_or_more)}"


def loops(value: LoopSummary | None) -> str:
    """``with a loop 12.5 % (5 / 40), mean 0.1, median 0, max 1``."""
    if value is None:
        return NONE
    counts = f"mean {value.mean:.1f}, median {value.median:g}, max {value.maximum}"
    return f"with a loop {share(value.scenes_with_loop)}, {counts}"


def storeys(value: dict[str, Share]) -> str:
    """``1: 25.0 % (2 / 8), 2: 62.5 % (5 / 8), 3: 12.5 % (1 / 8)`` (scenes by their number of storeys)."""
    return ", ".join(f"{count}: {share(scenes)}" for count, scenes in value.items())


def _bin(edges: tuple[float, ...], k: int) -> str:
    low, high = edges[k], edges[k + 1]
    return f"[{low:g}, {high:g})" if math.isfinite(high) else f">= {low:g}"


Row = tuple[str, Callable[[Item], str]]


def _scene_rows(stats: WorldStats) -> list[Row[SceneSetStats]]:
    config = stats.config
    kinds = list(dict.fromkeys(k for s in stats.scene_sets for k in s.doors_by_type))
    rows: list[Row[SceneSetStats]] = [
        ("scenes", lambda s: str(s.scenes)),
        ("storeys per scene", lambda s: storeys(s.storeys_per_scene)),
        ("rooms per scene (room labels)", lambda s: spread(s.rooms_per_scene)),
        (f"corridors per scene ({', '.join(config.corridors)})", lambda s: spread(s.corridors_per_scene)),
        ("doors per room (corridors not counted)", lambda s: degrees(s.doors_per_room)),
        *((f"doors: {kind}", _doors_of(kind)) for kind in kinds),
        ("junction degree, room graph (every node)", lambda s: degrees(s.junction_degree)),
        ("regions per scene (segmentation)", lambda s: spread(s.regions_per_scene)),
        ("junction degree, segmented regions", lambda s: degrees(s.region_degree)),
        ("loops, room graph", lambda s: loops(s.room_graph_loops)),
        (
            f"loops, enclosed islands (>= {config.room_island_extent:g} m with room labels, "
            f">= {config.plan_island_extent:g} m without)",
            lambda s: loops(s.island_loops),
        ),
        (
            f"navigable m^2, HM3D's agent ({config.hm3d_radius:g} m, {config.hm3d_height:g} m)",
            lambda s: spread(s.area_hm3d),
        ),
        (
            f"navigable m^2, drivenav's agent ({config.sim.agent_radius:g} m, {config.sim.agent_height:g} m)",
            lambda s: spread(s.area_agent),
        ),
    ]
    return rows


def _doors_of(kind: str) -> Callable[[SceneSetStats], str]:
    def cell(stats: SceneSetStats) -> str:
        return degrees(stats.doors_by_type.get(kind))

    return cell


def _episode_rows(stats: WorldStats) -> list[Row[EpisodeSetStats]]:
    config = stats.config
    rows: list[Row[EpisodeSetStats]] = [
        ("episodes", lambda e: str(e.episodes)),
        ("episodes in scenes of several storeys", lambda e: share(e.in_multi_storey_scenes)),
        (
            f"episodes needing a floor change (info.cross_floor, else no view point within {config.half_storey:g} m "
            "of the start's height)",
            lambda e: share(e.floor_change),
        ),
        ("geodesic m: mean / median / p90", lambda e: _percentiles(e.geodesic)),
        (f"episodes > {config.long_episode:g} m", lambda e: share(e.over_long)),
        *(
            (f"geodesic m {_bin(config.distance_edges, k)}", _bin_of(lambda e: e.geodesic_histogram, k))
            for k in range(len(config.distance_edges) - 1)
        ),
        ("geodesic / Euclidean: mean / median / p90", lambda e: _percentiles(e.ratio)),
        *((f"geodesic / Euclidean < {limit:g}", _below(f"{limit:g}")) for limit in config.straight_ratios),
        *(
            (f"geodesic / Euclidean {_bin(config.ratio_edges, k)}", _bin_of(lambda e: e.ratio_histogram, k))
            for k in range(len(config.ratio_edges) - 1)
        ),
    ]
    return rows


def _percentiles(value: Summary | None) -> str:
    return NONE if value is None else f"{value.mean:.2f} / {value.median:.2f} / {value.p90:.2f}"


def _bin_of(histogram: Callable[[EpisodeSetStats], Histogram], k: int) -> Callable[[EpisodeSetStats], str]:
    def cell(stats: EpisodeSetStats) -> str:
        counts = histogram(stats).counts
        return share(Share(counts[k], sum(counts)))

    return cell


def _below(limit: str) -> Callable[[EpisodeSetStats], str]:
    def cell(stats: EpisodeSetStats) -> str:
        value = stats.ratio_below.get(limit)
        return NONE if value is None else share(value)

    return cell


def _table(names: Sequence[str], columns: Sequence[Item], rows: Sequence[Row[Item]]) -> list[str]:
    lines = [f"| figure | {' | '.join(names)} |", "|---" * (len(names) + 1) + "|"]
    lines.extend(f"| {label} | {' | '.join(cell(c) for c in columns)} |" for label, cell in rows)
    return lines
