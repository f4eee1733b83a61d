"""HM3D-OVON-style episodes: starts filtered the way HM3D-OVON's episode generator filters them, and three
vocabulary splits like its validation sets.

The rules follow the generator of HM3D-OVON (Yokoyama, Ramrakhya et al., arXiv 2409.14296), read in
``naokiyokoyama/ovon``, ``ovon/dataset/objectnav_generator.py`` at commit 1e5903a2 (docs/world-vs-hm3d.md, source
[4]); its straightness thinning is the one of Habitat's PointNav generator (``_ratio_sample_rate`` in
``habitat/datasets/pointnav/pointnav_generator.py``). For a start drawn on the navigable grid:

- its geodesic distance to the category's nearest view point lies in 1-30 m (the generator's
  ``start_distance_limits``; :func:`drivenav.eval.episodes.start_cells`);
- the ratio of that geodesic distance to the straight-line distance to the same view point (the geodesically
  nearest one) is at least 1.05 (``min_geo_to_euc_ratio``), and the start is then kept with probability
  ``min(1, 20 (ratio - 0.98)^2)``, which thins out near-straight episodes: 0.10 at 1.05, 0.50 at 1.14, 1 from
  about 1.20 (:func:`keep_probability`);
- it lies on an island of navigable floor at least 1.5 m in radius (the generator's ``ISLAND_RADIUS_LIMIT``,
  Habitat's ``island_radius``: the largest distance of the island from its centroid), and, since a grid cell
  of the 2-D world always lies on the one reachable island, also on floor where the agent can turn: every point
  within one forward step (:attr:`~drivenav.types.SimConfig.forward_step`, 0.25 m) of the start is navigable, so
  the agent can turn to any heading and step forward;
- in a building, a start lies on a storey's floor (not on the stairs); :class:`~drivenav.benchmarks.generate.Storeys`
  may ask for a share of episodes that need a floor change (HM3D-OVON's released splits have none; benchmark v3
  asks for HM3D v1's share).

The generator samples starts around clusters of the navigable mesh; here a start is drawn uniformly from the
cells that pass the distance limits and the island rule, up to ``start_retries`` times per category (the
generator's ``start_retries``), as :func:`drivenav.eval.episodes.generate_episodes` draws v1's starts.

Splits (:data:`SPLITS`, membership by :func:`drivenav.envs.vocabulary.vocabulary_split`): ``val_seen`` names
a common category, ``val_seen_synonyms`` names a common category by one of its synonyms, ``val_unseen`` names a
category of the rest. Episode ``i`` belongs to split ``SPLITS[i % 3]`` (so any prefix is balanced), each split
goes round-robin over the scenes on its own and spreads over its categories (the least used first); each
episode's ``info["split"]`` names its split.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.benchmarks.generate import (
    ANY_FLOOR,
    EpisodeDraft,
    Start,
    Storeys,
    build_episode,
    cell_start,
    floor_info,
    least_used_first,
    start_cells,
    start_layers,
)
from drivenav.envs.embedded.goals import SceneGoals, scene_goals, view_points_of
from drivenav.envs.embedded.levels import Point3
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.vocabulary import VOCABULARY, Vocabulary, vocabulary_split
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.types import SimConfig

SPLITS = ("val_seen", "val_seen_synonyms", "val_unseen")
"""HM3D-OVON's validation splits, in the order episodes take them."""

SPLIT_KEY = "split"
"""The ``info`` key naming an episode's split."""


@dataclass(frozen=True)
class OvonRules:
    """The start filters of HM3D-OVON's generator (see the module docstring for the source of each default).

    ``min_ratio``: least geodesic / Euclidean ratio; ``thinning_scale`` and ``thinning_offset``: a start passing
    it is kept with probability ``min(1, thinning_scale (ratio - thinning_offset)^2)``; ``island_radius``: least
    radius (m) of the start's island of navigable floor; ``start_retries``: starts drawn per category before
    the next category is tried.
    """

    min_ratio: float = 1.05
    thinning_scale: float = 20.0
    thinning_offset: float = 0.98
    island_radius: float = 1.5
    start_retries: int = 1000


def keep_probability(ratio: float, rules: OvonRules = OvonRules()) -> float:
    """The chance a start whose geodesic / Euclidean ratio passed ``min_ratio`` is kept (Habitat's PointNav
    ``_ratio_sample_rate``, which HM3D-OVON's generator applies as is): 0.098 at 1.05, 1 from about 1.204."""
    return min(1.0, rules.thinning_scale * (ratio - rules.thinning_offset) ** 2)


def split_categories(vocab: Vocabulary = VOCABULARY) -> dict[str, frozenset[str]]:
    """The categories each split's episodes may name: the seen ones (by name, and by synonym where they have
    one), the unseen ones by name."""
    split = vocabulary_split(vocab)
    with_synonyms = frozenset(name for name in split.seen if vocab.synonyms(name))
    return dict(zip(SPLITS, (frozenset(split.seen), with_synonyms, frozenset(split.unseen)), strict=True))


def island_radius(island: NDArray[np.bool_], resolution: float) -> float:
    """The largest distance (m) from the island's centroid to the centre of one of its cells (Habitat's
    ``island_radius``: the radius of the circle about the island's centroid that holds it), in plan (a building's
    layers taken together)."""
    cells = np.argwhere(island)[:, -2:].astype(np.float64)
    if len(cells) == 0:
        return 0.0
    return float(np.max(np.linalg.norm(cells - cells.mean(axis=0), axis=1)) * resolution)


def turnable(reachable: NDArray[np.bool_], resolution: float, clearance: float) -> NDArray[np.bool_]:
    """The reachable cells from whose centre every cell centre closer than ``clearance`` (m) is reachable too
    (per layer of a building: of its own surface)."""
    if reachable.ndim == 3:
        return np.stack([turnable(layer, resolution, clearance) for layer in reachable])
    distance = ndimage.distance_transform_edt(np.pad(reachable, 1))[1:-1, 1:-1] * resolution
    return np.asarray(reachable & (distance >= clearance))


@dataclass
class OvonScene:
    """A scene's goals and the cells a start may be drawn from (on an island large enough, with room to turn)."""

    goals: SceneGoals
    allowed: NDArray[np.bool_]


def ovon_scene(goals: SceneGoals, sim: SimConfig, rules: OvonRules) -> OvonScene:
    """The start cells of one scene: none where the reachable island is smaller than ``rules.island_radius``."""
    resolution = goals.grid.resolution
    if island_radius(goals.reachable, resolution) < rules.island_radius:
        return OvonScene(goals, np.zeros_like(goals.reachable))
    return OvonScene(goals, turnable(goals.reachable, resolution, sim.forward_step))


def straightness(goals: SceneGoals, category: str, start: Point3, geodesic: float) -> float:
    """Geodesic / Euclidean distance from ``start`` to the category's view point that is nearest by geodesic
    distance (the generator's ``dist_ratio``): one geodesic solve from the start finds that view point."""
    points = view_points_of(goals.goals[category])
    from_start = goals.terrain.field([start])
    distances = [from_start.at(*p) for p in points]
    k = int(np.argmin(distances))
    return _ratio(geodesic, math.dist(start, points[k]))


def _ratio(geodesic: float, euclidean: float) -> float:
    return geodesic / euclidean if euclidean > 0.0 else math.inf


def filtered_start(
    scene: OvonScene, category: str, rng: np.random.Generator, rules: OvonRules, cross: bool | None = None
) -> Start | None:
    """A start for ``category`` that passes every filter (on a storey without an instance of it where ``cross``,
    with one where not ``cross``), or None after ``rules.start_retries`` draws.

    The straight-line distance to the geodesically nearest view point is at least the distance to the nearest
    view point, so a start whose ratio to the latter is below ``min_ratio`` is rejected without the solve of
    :func:`straightness` (the same starts pass either way, with the same draws)."""
    layers = start_layers(scene.goals, category, cross)
    cells = start_cells(scene.goals, category, scene.allowed if layers is None else scene.allowed & layers)
    if len(cells) == 0:
        return None
    points = np.asarray(view_points_of(scene.goals.goals[category]))
    for _ in range(rules.start_retries):
        (x, y, height), geodesic = cell_start(scene.goals, category, cells[rng.integers(len(cells))])
        start = (round(x, 4), round(y, 4), height)  # as the episode stores it
        across = np.hypot(points[:, 0] - start[0], points[:, 1] - start[1])
        nearest = float(np.min(np.hypot(across, points[:, 2] - height)))
        if _ratio(geodesic, nearest) < rules.min_ratio:
            continue
        ratio = straightness(scene.goals, category, start, geodesic)
        if ratio < rules.min_ratio or rng.random() > keep_probability(ratio, rules):
            continue
        return start, geodesic
    return None


def generate_ovon_episodes(
    library: SceneLibrary,
    num: int,
    seed: int,
    sim: SimConfig | None = None,
    rules: OvonRules = OvonRules(),
    storeys: Storeys = ANY_FLOOR,
) -> list[Episode]:
    """``num`` episodes, episode ``i`` of split ``SPLITS[i % 3]``, each split round-robin over the library's
    scenes (a scene without a start that passes the filters for a category of the split is skipped for that
    turn), starts on a storey chosen as ``storeys`` says. Deterministic in ``seed``; generated in order, so the
    first N are the episodes of ``num = N``. No scene with such a start at all for a split is an
    :class:`InputError`."""
    generation = _Generation(library, sim or SimConfig(), rules, np.random.default_rng(seed), storeys)
    episodes: list[Episode] = []
    while len(episodes) < num and library.scene_ids:
        episodes.append(generation.next_episode(len(episodes)))
    return episodes


@dataclass
class _Generation:
    """The state of one generation: scenes loaded so far, each split's next scene and its categories' use."""

    library: SceneLibrary
    sim: SimConfig
    rules: OvonRules
    rng: np.random.Generator
    storeys: Storeys
    allowed: dict[str, frozenset[str]] = field(default_factory=split_categories)
    scenes: dict[str, OvonScene] = field(default_factory=dict)
    used: dict[str, Counter[str]] = field(default_factory=lambda: {name: Counter() for name in SPLITS})
    turns: Counter[str] = field(default_factory=Counter)

    def scene(self, scene_id: str) -> OvonScene:
        if scene_id not in self.scenes:
            goals = scene_goals(self.library.load(scene_id), self.sim)
            self.scenes[scene_id] = ovon_scene(goals, self.sim, self.rules)
        return self.scenes[scene_id]

    def next_episode(self, index: int) -> Episode:
        """Episode ``index``: of split ``SPLITS[index % 3]``, in the first scene from the split's turn on that has
        a start for one of the split's categories."""
        split = SPLITS[index % len(SPLITS)]
        scene_ids = self.library.scene_ids
        for _ in scene_ids:
            scene_id = scene_ids[self.turns[split] % len(scene_ids)]
            self.turns[split] += 1
            draft = self.draft(str(index), scene_id, split)
            if draft is not None:
                self.used[split][draft.category] += 1
                return build_episode(draft, self.scene(scene_id).goals, self.rng)
        expected = f"a scene with a start for a {split} category that passes HM3D-OVON's filters"
        raise InputError("command line", "--scenes", expected, f"none of {len(scene_ids)} in {self.library.spec}")

    def draft(self, episode_id: str, scene_id: str, split: str) -> EpisodeDraft | None:
        """The split's episode in this scene: the least-used category of the split with a start that passes."""
        scene = self.scene(scene_id)
        present = [c for c in scene.goals.goals if c in self.allowed[split]]
        cross = self.storeys.draw(scene.goals, self.rng)
        for category in least_used_first(present, self.used[split], self.rng):
            start = filtered_start(scene, category, self.rng, self.rules, cross)
            if start is None:
                continue
            synonym = split == SPLITS[1]
            text = _pick(VOCABULARY.synonyms(category), self.rng) if synonym else category
            extra = ((SPLIT_KEY, split), *floor_info(scene.goals, category, start))
            return EpisodeDraft(episode_id, scene_id, category, start, text, synonym, extra)
        return None


def _pick(names: Sequence[str], rng: np.random.Generator) -> str:
    return str(names[int(rng.integers(len(names)))])


def episode_splits(episodes: Sequence[Episode]) -> dict[str, str]:
    """Each episode's split by id, for the episodes that name one in ``info["split"]`` (empty for v1's)."""
    return {e.episode_id: str(e.info[SPLIT_KEY]) for e in episodes if isinstance(e.info.get(SPLIT_KEY), str)}
