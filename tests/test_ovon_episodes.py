"""HM3D-OVON-style episodes: every start passes the generator's filters (checked with distances computed here, by
Dijkstra on the navigable grid and straight lines), the vocabulary splits, determinism, and v1 left as it was."""

from __future__ import annotations

import hashlib
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from drivenav.benchmarks.benchmark import BENCHMARK_V2, BENCHMARKS
from drivenav.benchmarks.ovon_episodes import (
    SPLITS,
    OvonRules,
    generate_ovon_episodes,
    island_radius,
    keep_probability,
    split_categories,
)
from drivenav.cli import main
from drivenav.envs.embedded.geodesic import largest_component
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.vocabulary import VOCABULARY, vocabulary_split
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.episodes import load_episodes, save_episodes, validate_for_scenes
from drivenav.types import SimConfig

SPEC, SEED, COUNT = "procedural:3", 7, 15
DIAGONAL_EXCESS = 1.0 / math.cos(math.pi / 8)  # the most an 8-neighbour path overestimates a straight line


@pytest.fixture(scope="module")
def library() -> SceneLibrary:
    return SceneLibrary(SPEC, SEED)


@pytest.fixture(scope="module")
def episodes(library: SceneLibrary) -> list[Episode]:
    return generate_ovon_episodes(library, COUNT, SEED)


def _reachable(library: SceneLibrary, scene_id: str) -> NDArray[np.bool_]:
    sim = SimConfig()
    return largest_component(library.load(scene_id).navigable_grid(sim.agent_radius, sim.agent_height))


def _dijkstra_from(reachable: NDArray[np.bool_], cell: tuple[int, int]) -> NDArray[np.float64]:
    """Shortest 8-neighbour path lengths in cells from ``cell`` over ``reachable`` (a diagonal step needs both
    cells beside it free), per cell; ``inf`` off it."""
    index = -np.ones(reachable.shape, dtype=np.int64)
    index[reachable] = np.arange(int(reachable.sum()))
    padded = np.pad(reachable, 1)
    rows, cols = np.nonzero(reachable)
    sources, targets, weights = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ok = padded[rows + 1 + dr, cols + 1 + dc]
        if dr and dc:
            ok &= padded[rows + 1 + dr, cols + 1] & padded[rows + 1, cols + 1 + dc]
        sources.append(index[rows[ok], cols[ok]])
        targets.append(index[rows[ok] + dr, cols[ok] + dc])
        weights.append(np.full(int(ok.sum()), math.hypot(dr, dc)))
    size = int(reachable.sum())
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(sources), np.concatenate(targets))), (size, size))
    out = np.full(reachable.shape, np.inf)
    out[reachable] = dijkstra(graph.tocsr(), directed=False, indices=int(index[cell]))
    return out


def test_keep_probability_is_habitats_ratio_sample_rate() -> None:
    # 20 (r - 0.98)^2: 20 * 0.07^2 = 0.098, 20 * 0.12^2 = 0.288, 20 * 0.22^2 = 0.968, then capped at 1.
    assert keep_probability(1.05) == pytest.approx(0.098)
    assert keep_probability(1.10) == pytest.approx(0.288)
    assert keep_probability(1.20) == pytest.approx(0.968)
    assert keep_probability(1.21) == 1.0 and keep_probability(3.0) == 1.0


def test_the_splits_are_disjoint_and_decided_by_the_vocabulary() -> None:
    split = vocabulary_split(VOCABULARY)
    assert set(split.seen).isdisjoint(split.unseen)
    assert sorted(split.seen + split.unseen) == sorted(VOCABULARY.categories())
    # anchors (a bed in every bedroom, a toy chest in every playroom: weight 2.5) and weight >= 3 are common
    assert {"bed", "toy chest", "dresser", "armchair", "towel"} <= set(split.seen)
    assert {"crib", "bidet", "piano", "stool", "kitchen island"} <= set(split.unseen)  # weights 0.8, 0.4, 0.6, 2, 1.5
    categories = split_categories()
    assert list(categories) == list(SPLITS)
    assert categories["val_seen_synonyms"] <= categories["val_seen"]
    assert all(VOCABULARY.synonyms(name) for name in categories["val_seen_synonyms"])
    assert categories["val_seen"].isdisjoint(categories["val_unseen"])


def test_each_episode_names_its_splits_category(episodes: list[Episode]) -> None:
    split = vocabulary_split(VOCABULARY)
    assert len(episodes) == COUNT
    for i, episode in enumerate(episodes):
        name, category = episode.info["split"], str(episode.info["canonical_category"])
        assert name == SPLITS[i % 3]
        if name == "val_unseen":
            assert category in split.unseen and episode.object_category == category
        elif name == "val_seen":
            assert category in split.seen and episode.object_category == category
        else:
            assert category in split.seen and episode.object_category in VOCABULARY.synonyms(category)
        assert episode.info["synonym"] is (name == "val_seen_synonyms")
        assert all(goal.object_category == category for goal in episode.goals)


def test_every_start_passes_hm3d_ovons_filters(library: SceneLibrary, episodes: list[Episode]) -> None:
    sim = SimConfig()
    for episode in episodes:
        scene = library.load(episode.scene_id)
        reachable, resolution = _reachable(library, episode.scene_id), scene.grid.resolution
        start = scene.grid.cell_at(*episode.start_xy)
        lengths = _dijkstra_from(reachable, start) * resolution
        points = episode.view_points_xy()
        by_path = [float(lengths[scene.grid.cell_at(*p)]) for p in points]
        k = int(np.argmin(by_path))
        geodesic = episode.geodesic_distance
        # the stored distance (Fast Marching) is a shortest path: at most the 8-neighbour path, and not shorter
        # than it by more than an 8-neighbour path can overestimate
        assert by_path[k] / DIAGONAL_EXCESS - resolution <= geodesic <= by_path[k] + resolution
        assert 1.0 <= geodesic <= 30.0
        euclidean = math.dist(episode.start_xy, points[k])
        assert by_path[k] / euclidean >= 1.05
        assert geodesic / euclidean >= 1.05 * 0.98  # the generator's nearest view point may differ by a near tie
        # room to turn: every cell centre closer than one forward step to the start's is reachable
        steps = math.ceil(sim.forward_step / resolution)
        for dr in range(-steps, steps + 1):
            for dc in range(-steps, steps + 1):
                if math.hypot(dr, dc) * resolution < sim.forward_step:
                    assert reachable[start[0] + dr, start[1] + dc]


def test_near_straight_starts_are_thinned_and_a_small_island_has_none() -> None:
    one = SceneLibrary("procedural:1", SEED)
    assert generate_ovon_episodes(one, 1, SEED, rules=OvonRules(start_retries=5))  # passes with the defaults
    with pytest.raises(InputError, match="--scenes"):  # every start that passes 1.05 is dropped at probability 0
        generate_ovon_episodes(one, 1, SEED, rules=OvonRules(thinning_scale=0.0, start_retries=5))
    with pytest.raises(InputError, match="val_seen"):  # no island 1 km in radius
        generate_ovon_episodes(one, 1, SEED, rules=OvonRules(island_radius=1000.0))
    island = np.zeros((5, 7), dtype=bool)
    island[2, 1:6] = True  # five cells in a row: 2 cells (0.1 m) from the centroid to either end
    assert island_radius(island, 0.05) == pytest.approx(0.1)


def test_generation_is_deterministic_and_a_prefix_is_the_same_episodes(
    library: SceneLibrary, episodes: list[Episode], tmp_path: Path
) -> None:
    again = generate_ovon_episodes(library, COUNT, SEED)
    save_episodes(episodes, tmp_path / "a.json.gz")
    save_episodes(again, tmp_path / "b.json.gz")
    assert (tmp_path / "a.json.gz").read_bytes() == (tmp_path / "b.json.gz").read_bytes()
    assert generate_ovon_episodes(library, 6, SEED) == episodes[:6]
    assert generate_ovon_episodes(library, 6, SEED + 1) != episodes[:6]


def test_benchmark_v2_is_300_ovon_episodes_on_homes() -> None:
    assert BENCHMARKS["v2"] is BENCHMARK_V2
    assert (BENCHMARK_V2.episodes, BENCHMARK_V2.generator) == (300, "ovon")
    assert BENCHMARK_V2.scenes.startswith("homes:")


def test_benchmark_v1_gives_the_bytes_it_was_published_with(tmp_path: Path) -> None:
    out = tmp_path / "v1.json.gz"
    assert main(["benchmark", "generate", "--version", "v1", "--out", str(out)]) == 0
    digest = "3de8fb637e7355d64ad7463deb23e84d6365c5138732876b8a27d882bf4955d8"  # docs/benchmarks.md
    assert hashlib.sha256(out.read_bytes()).hexdigest() == digest


def test_benchmark_v2_is_frozen_with_100_episodes_per_split(tmp_path: Path) -> None:
    out = tmp_path / "v2.json.gz"
    assert main(["benchmark", "generate", "--version", "v2", "--out", str(out)]) == 0
    digest = "8c08b1f3328280e5f4266a04d251df51a952c9a8e7403b19f3ea6d03ba4e6d9a"
    assert hashlib.sha256(out.read_bytes()).hexdigest() == digest
    frozen = load_episodes(out)
    assert [e.episode_id for e in frozen] == [str(i) for i in range(300)]
    assert Counter(e.info["split"] for e in frozen) == dict.fromkeys(SPLITS, 100)
    assert len({e.scene_id for e in frozen}) == 50
    library = SceneLibrary(BENCHMARK_V2.scenes, BENCHMARK_V2.seed)
    validate_for_scenes(frozen[:12], library, out, SimConfig())  # still valid in today's homes
