"""Episodes generated over a scene set (the embedded world's ``--episodes N`` and benchmark v1): HM3D-OVON-style
episodes spread round-robin over the scenes and across categories, each with every instance of its category as a
goal, a start 1-30 m by geodesic distance from the nearest view point (HM3D-OVON's limits) and, in a quarter of
them, the target named by a synonym (as HM3D-OVON's val_seen_synonyms)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.goals import SceneGoals, objects_source, scene_goals
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.types import SimConfig

MIN_GEODESIC = 1.0  # metres, start to nearest view point
MAX_GEODESIC = 30.0
SYNONYM_SHARE = 0.25  # share of episodes naming the target by a synonym


def _synonyms(category: str) -> tuple[str, ...]:
    from drivenav.envs.vocabulary import synonyms

    try:
        return tuple(synonyms(category))
    except KeyError:
        return ()


def start_cells(goals: SceneGoals, category: str, allowed: NDArray[np.bool_] | None = None) -> NDArray[np.int64]:
    """The ``(row, col)`` cells, in row-major order, that are reachable (and ``allowed``, if given) and lie
    1-30 m by geodesic distance from the category's nearest view point (HM3D-OVON's start distance limits)."""
    distances = goals.field_for(category).distances
    mask = goals.reachable & (distances >= MIN_GEODESIC) & (distances <= MAX_GEODESIC)
    cells: NDArray[np.int64] = np.argwhere(mask if allowed is None else mask & allowed)
    return cells


def cell_start(goals: SceneGoals, category: str, cell: NDArray[np.int64]) -> tuple[tuple[float, float], float]:
    """A start at ``cell``'s centre: its world point and its geodesic distance to the category's view points."""
    x, y = goals.scene.grid.cell_to_world(cell)
    return (float(x), float(y)), float(goals.field_for(category).distances[cell[0], cell[1]])


def _sample_start(
    goals: SceneGoals, category: str, rng: np.random.Generator
) -> tuple[tuple[float, float], float] | None:
    """A reachable start cell whose geodesic distance to the category lies in the allowed range."""
    candidates = start_cells(goals, category)
    if len(candidates) == 0:
        return None
    return cell_start(goals, category, candidates[rng.integers(len(candidates))])


def generate_episodes(library: SceneLibrary, num: int, seed: int, sim: SimConfig | None = None) -> list[Episode]:
    """``num`` episodes spread round-robin over the library's scenes and across categories.

    Deterministic in ``seed``. A scene without any start 1-30 m from an object it holds is an :class:`InputError`.
    """
    sim = sim or SimConfig()
    rng = np.random.default_rng(seed)
    contexts: dict[str, SceneGoals] = {}
    used: Counter[str] = Counter()
    episodes: list[Episode] = []
    scene_ids = library.scene_ids
    turn = 0
    while len(episodes) < num and scene_ids:
        scene_id = scene_ids[turn % len(scene_ids)]
        if scene_id not in contexts:
            contexts[scene_id] = scene_goals(library.load(scene_id), sim)
        episode = _make_episode(str(len(episodes)), scene_id, contexts[scene_id], used, rng)
        if episode is None:
            expected = f"a start {MIN_GEODESIC:g}-{MAX_GEODESIC:g} m by geodesic distance from one of its objects"
            raise InputError(objects_source(contexts[scene_id].scene), "objects", expected, "none")
        episodes.append(episode)
        used[episode.info["canonical_category"]] += 1
        turn += 1
    return episodes


def _make_episode(
    episode_id: str, scene_id: str, goals: SceneGoals, used: Counter[str], rng: np.random.Generator
) -> Episode | None:
    for category in least_used_first(goals.goals, used, rng):
        start = _sample_start(goals, category, rng)
        if start is None:
            continue
        names = _synonyms(category)
        synonym = bool(names) and rng.random() < SYNONYM_SHARE
        text = str(names[rng.integers(len(names))]) if synonym else category
        return build_episode(EpisodeDraft(episode_id, scene_id, category, start, text, synonym), goals, rng)
    return None


def least_used_first(categories: Iterable[str], used: Counter[str], rng: np.random.Generator) -> list[str]:
    """``categories`` in name order, shuffled by one permutation draw, then stably sorted by how often ``used``
    has them: the least-used first, in random order among ties (the spread over categories of every generator)."""
    present = sorted(categories)
    shuffled = [present[i] for i in rng.permutation(len(present))]
    return sorted(shuffled, key=lambda c: used[c])


@dataclass(frozen=True)
class EpisodeDraft:
    """What a generator chose for an episode: its id and scene, the canonical category, the start (world point,
    geodesic distance to the nearest view point), the text the agent is given and whether it is a synonym, and
    further ``info`` keys (after the three every episode has)."""

    episode_id: str
    scene_id: str
    category: str
    start: tuple[tuple[float, float], float]
    text: str
    synonym: bool
    extra: tuple[tuple[str, str], ...] = ()


def build_episode(draft: EpisodeDraft, goals: SceneGoals, rng: np.random.Generator) -> Episode:
    """The episode of ``draft`` with every goal of its category, its start rounded to 0.1 mm and a heading drawn
    uniformly in [0, 2 pi) from ``rng`` (HM3D-OVON's generator draws its start angle the same way)."""
    (x, y), geodesic = draft.start
    info: JsonObject = {
        "geodesic_distance": round(geodesic, 4),
        "canonical_category": draft.category,
        "synonym": draft.synonym,
    }
    return Episode(
        episode_id=draft.episode_id,
        scene_id=draft.scene_id,
        start_position=world_to_habitat(round(x, 4), round(y, 4)),
        start_rotation=yaw_to_quaternion(float(rng.uniform(0.0, 2.0 * math.pi))),
        object_category=draft.text,
        goals=tuple(goals.goals[draft.category]),
        info=info | dict(draft.extra),
    )
