"""Episodes generated over a scene set (the embedded world's ``--episodes N`` and benchmark v1): HM3D-OVON-style
episodes spread round-robin over the scenes and across categories, each with every instance of its category as a
goal, a start 1-30 m by geodesic distance from the nearest view point (HM3D-OVON's limits) and, in a quarter of
them, the target named by a synonym (as HM3D-OVON's val_seen_synonyms). In a building a start lies on a storey's
floor, and :class:`Storeys` can ask for a share of episodes that need a floor change."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import Building, storeys_of
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


Start = tuple[tuple[float, float, float], float]
"""A drawn start: its world point with its height, and its geodesic distance to the category's nearest view point."""


def start_cells(goals: SceneGoals, category: str, allowed: NDArray[np.bool_] | None = None) -> NDArray[np.int64]:
    """The ``(layer, row, col)`` cells, in index order, that lie on the reachable floor (in a building: a storey's
    floor, not its stairs; and ``allowed``, if given) and 1-30 m by geodesic distance from the category's nearest
    view point (HM3D-OVON's start distance limits)."""
    distances = goals.field_for(category).distances
    mask = floor_cells(goals) & (distances >= MIN_GEODESIC) & (distances <= MAX_GEODESIC)
    cells: NDArray[np.int64] = np.argwhere(mask if allowed is None else mask & allowed)
    return cells


def floor_cells(goals: SceneGoals) -> NDArray[np.bool_]:
    """The reachable cells that lie on a storey's floor (every reachable cell of a one-floor scene)."""
    elevations = np.array([s.elevation for s in storeys_of(goals.scene)])[:, None, None]
    on_floor: NDArray[np.bool_] = goals.reachable & (goals.terrain.heights == elevations)
    return on_floor


def cell_start(goals: SceneGoals, category: str, cell: NDArray[np.int64]) -> Start:
    """A start at ``cell``'s centre: its world point with its height and its geodesic distance to the category's
    view points."""
    layer, row, col = (int(v) for v in cell)
    x, y = goals.grid.cell_to_world((row, col))
    height = float(goals.terrain.heights[layer, row, col])
    return (float(x), float(y), height), float(goals.field_for(category).distances[layer, row, col])


def _sample_start(goals: SceneGoals, category: str, rng: np.random.Generator, cross: bool | None) -> Start | None:
    """A start cell on the reachable floor (of a storey ``cross`` allows) whose geodesic distance to the category
    lies in the allowed range."""
    candidates = start_cells(goals, category, start_layers(goals, category, cross))
    if len(candidates) == 0:
        return None
    return cell_start(goals, category, candidates[rng.integers(len(candidates))])


@dataclass(frozen=True)
class Storeys:
    """Which floor an episode's start may lie on, in a scene of several storeys.

    ``cross_floor`` (None: any floor): the share of episodes whose start lies on a storey without an instance of
    their category, so that they need a floor change (ASCENT's and the HM3D v1 count's definition); the others
    start on a storey with one. It is drawn once per episode and scene, in scenes of several storeys only, so one-floor
    scene sets give the episodes they always gave.
    """

    cross_floor: float | None = None

    def draw(self, goals: SceneGoals, rng: np.random.Generator) -> bool | None:
        """Whether the episode drafted in this scene must need a floor change (None: any floor)."""
        if self.cross_floor is None or len(storeys_of(goals.scene)) == 1:
            return None
        return bool(rng.random() < self.cross_floor)


def start_layers(goals: SceneGoals, category: str, cross: bool | None) -> NDArray[np.bool_] | None:
    """The layers a start may lie on: those without an instance of ``category`` (``cross``), those with one (not
    ``cross``), or all (None)."""
    if cross is None:
        return None
    holding = goal_storeys(goals, category)
    layers = np.array([(j not in holding) == cross for j in range(len(storeys_of(goals.scene)))])
    return np.broadcast_to(layers[:, None, None], goals.reachable.shape)


def goal_storeys(goals: SceneGoals, category: str) -> frozenset[int]:
    """The storeys holding an instance of ``category`` (``{0}`` in a one-floor scene)."""
    scene = goals.scene
    if not isinstance(scene, Building):
        return frozenset({0})
    return frozenset(scene.storey_of(goal.object_id) for goal in goals.goals[category])


def floor_info(goals: SceneGoals, category: str, start: Start) -> tuple[tuple[str, object], ...]:
    """The ``info`` keys of an episode in a scene of several storeys (none in a one-floor scene): the start's
    storey, the storeys holding a goal, and whether it needs a floor change."""
    scene = goals.scene
    if not isinstance(scene, Building) or len(scene.storeys) == 1:
        return ()
    start_floor = scene.storey_at(start[0][2])
    goal_floors = sorted(goal_storeys(goals, category))
    return (("start_floor", start_floor), ("goal_floors", goal_floors), ("cross_floor", start_floor not in goal_floors))


ANY_FLOOR = Storeys()
"""Starts on any floor (the share of episodes that need a floor change left to the scenes)."""


def generate_episodes(
    library: SceneLibrary, num: int, seed: int, sim: SimConfig | None = None, storeys: Storeys = ANY_FLOOR
) -> list[Episode]:
    """``num`` episodes spread round-robin over the library's scenes and across categories, starts on a storey
    chosen as ``storeys`` says.

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
        episode = _make_episode(str(len(episodes)), scene_id, contexts[scene_id], used, rng, storeys)
        if episode is None:
            expected = f"a start {MIN_GEODESIC:g}-{MAX_GEODESIC:g} m by geodesic distance from one of its objects"
            raise InputError(objects_source(contexts[scene_id].scene), "objects", expected, "none")
        episodes.append(episode)
        used[episode.info["canonical_category"]] += 1
        turn += 1
    return episodes


def _make_episode(
    episode_id: str,
    scene_id: str,
    goals: SceneGoals,
    used: Counter[str],
    rng: np.random.Generator,
    storeys: Storeys,
) -> Episode | None:
    cross = storeys.draw(goals, rng)
    for category in least_used_first(goals.goals, used, rng):
        start = _sample_start(goals, category, rng, cross)
        if start is None:
            continue
        names = _synonyms(category)
        synonym = bool(names) and rng.random() < SYNONYM_SHARE
        text = str(names[rng.integers(len(names))]) if synonym else category
        extra = floor_info(goals, category, start)
        return build_episode(EpisodeDraft(episode_id, scene_id, category, start, text, synonym, extra), goals, rng)
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
    start: Start
    text: str
    synonym: bool
    extra: tuple[tuple[str, object], ...] = ()


def build_episode(draft: EpisodeDraft, goals: SceneGoals, rng: np.random.Generator) -> Episode:
    """The episode of ``draft`` with every goal of its category, its start rounded to 0.1 mm (at its floor's
    height) and a heading drawn uniformly in [0, 2 pi) from ``rng`` (HM3D-OVON's generator draws its start angle
    the same way)."""
    (x, y, height), geodesic = draft.start
    info: JsonObject = {
        "geodesic_distance": round(geodesic, 4),
        "canonical_category": draft.category,
        "synonym": draft.synonym,
    }
    return Episode(
        episode_id=draft.episode_id,
        scene_id=draft.scene_id,
        start_position=world_to_habitat(round(x, 4), round(y, 4), height),
        start_rotation=yaw_to_quaternion(float(rng.uniform(0.0, 2.0 * math.pi))),
        object_category=draft.text,
        goals=tuple(goals.goals[draft.category]),
        info=info | dict(draft.extra),
    )
