"""HM3D-OVON-style episode files: generation over a scene set, and validated reading and writing.

A file is gzip-compressed JSON ``{"episodes": [...]}``; each episode carries ``episode_id``, ``scene_id``,
``start_position`` and ``start_rotation`` (Habitat's y-up frame, see :mod:`drivenav.envs.episode`),
``object_category`` (the text given to the agent, a synonym in some episodes as in HM3D-OVON's
val_seen_synonyms), ``goals`` (every instance of the category with ``position`` and ``view_points``) and
``info`` (``geodesic_distance``, ``canonical_category``, ``synonym``).
"""

from __future__ import annotations

import gzip
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.episode import (
    Episode,
    ObjectGoal,
    Quat,
    Vec3,
    ViewPoint,
    world_to_habitat,
    yaw_to_quaternion,
)
from drivenav.envs.geodesic import GeodesicField, largest_component
from drivenav.envs.library import SceneLibrary
from drivenav.envs.scene import Scene
from drivenav.errors import InputError
from drivenav.eval.goals import object_goal
from drivenav.types import SimConfig
from drivenav.validation import Fields

MIN_GEODESIC = 1.0  # metres, start to nearest view point
MAX_GEODESIC = 30.0
SYNONYM_SHARE = 0.25  # share of episodes naming the target by a synonym


@dataclass
class SceneGoals:
    """Per scene: the reachable region, goals by category, and geodesic fields (built lazily)."""

    scene: Scene
    reachable: NDArray[np.bool_]
    goals: dict[str, list[ObjectGoal]]
    fields: dict[str, GeodesicField] = field(default_factory=dict)

    def field_for(self, category: str) -> GeodesicField:
        if category not in self.fields:
            points = [vp.xy for goal in self.goals[category] for vp in goal.view_points]
            self.fields[category] = GeodesicField(self.reachable, self.scene.grid, points)
        return self.fields[category]


def scene_goals(scene: Scene, sim: SimConfig) -> SceneGoals:
    """Goals of every object that has at least one reachable view point, grouped by category.

    A scene without free space the agent fits in, or without an object it can reach, is an :class:`InputError`
    naming the scene's file (never a scene silently left out of the episodes).
    """
    source = scene.source if scene.source != "procedural" else f"procedural house {scene.scene_id}"
    reachable = largest_component(scene.navigable_grid(sim.agent_radius, sim.agent_height))
    if not reachable.any():
        expected = f"free space an agent of radius {sim.agent_radius} m fits in"
        raise InputError(source, "image", expected, "only walls, unknown or too narrow space")
    goals: dict[str, list[ObjectGoal]] = {}
    for obj in scene.objects:
        goal = object_goal(scene, obj, reachable, sim)
        if goal.view_points:
            goals.setdefault(obj.category, []).append(goal)
    if not goals:
        expected = "objects seen from where the agent can go (objects.json, or free space to place them in)"
        raise InputError(source, "objects", expected, f"{len(scene.objects)} objects, none reachable")
    return SceneGoals(scene, reachable, goals)


def _synonyms(category: str) -> tuple[str, ...]:
    from drivenav.envs.vocabulary import synonyms

    try:
        return tuple(synonyms(category))
    except KeyError:
        return ()


def _sample_start(
    goals: SceneGoals, category: str, rng: np.random.Generator
) -> tuple[tuple[float, float], float] | None:
    """A reachable start cell whose geodesic distance to the category lies in the allowed range."""
    distances = goals.field_for(category).distances
    candidates = np.argwhere(goals.reachable & (distances >= MIN_GEODESIC) & (distances <= MAX_GEODESIC))
    if len(candidates) == 0:
        return None
    cell = candidates[rng.integers(len(candidates))]
    x, y = goals.scene.grid.cell_to_world(cell)
    return (float(x), float(y)), float(distances[cell[0], cell[1]])


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
            source = contexts[scene_id].scene.source or scene_id
            expected = f"a start {MIN_GEODESIC:g}-{MAX_GEODESIC:g} m by geodesic distance from one of its objects"
            raise InputError(source, "objects", expected, "none")
        episodes.append(episode)
        used[episode.info["canonical_category"]] += 1
        turn += 1
    return episodes


def _make_episode(
    episode_id: str, scene_id: str, goals: SceneGoals, used: Counter[str], rng: np.random.Generator
) -> Episode | None:
    present = sorted(goals.goals)
    shuffled = [present[i] for i in rng.permutation(len(present))]
    categories = sorted(shuffled, key=lambda c: used[c])  # least-used first, random among ties
    for category in categories:
        start = _sample_start(goals, category, rng)
        if start is None:
            continue
        (x, y), geodesic = start
        names = _synonyms(category)
        synonym = bool(names) and rng.random() < SYNONYM_SHARE
        text = str(names[rng.integers(len(names))]) if synonym else category
        return Episode(
            episode_id=episode_id,
            scene_id=scene_id,
            start_position=world_to_habitat(round(x, 4), round(y, 4)),
            start_rotation=yaw_to_quaternion(float(rng.uniform(0.0, 2.0 * math.pi))),
            object_category=text,
            goals=tuple(goals.goals[category]),
            info={
                "geodesic_distance": round(geodesic, 4),
                "canonical_category": category,
                "synonym": synonym,
            },
        )
    return None


def _round(values: tuple[float, ...]) -> list[float]:
    return [round(float(v), 4) for v in values]


def episode_to_dict(episode: Episode) -> dict[str, Any]:
    """The HM3D-OVON JSON form of an episode."""
    return {
        "episode_id": episode.episode_id,
        "scene_id": episode.scene_id,
        "start_position": _round(episode.start_position),
        "start_rotation": _round(episode.start_rotation),
        "object_category": episode.object_category,
        "goals": [
            {
                "object_id": goal.object_id,
                "object_category": goal.object_category,
                "position": _round(goal.position),
                "view_points": [
                    {
                        "agent_state": {"position": _round(vp.position), "rotation": _round(vp.rotation)},
                        "iou": vp.iou,
                    }
                    for vp in goal.view_points
                ],
            }
            for goal in episode.goals
        ],
        "info": dict(episode.info),
    }


def save_episodes(episodes: list[Episode], path: str | Path) -> None:
    """Write a json.gz episode file, byte-identical for identical episodes."""
    payload = json.dumps({"episodes": [episode_to_dict(e) for e in episodes]}, separators=(",", ":"))
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    with target.open("wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz:
        gz.write(payload.encode())


def load_episodes(path: str | Path) -> list[Episode]:
    """Read and validate an episode file (json.gz, or plain .json)."""
    source = Path(path)
    if not source.is_file():
        raise InputError(source, "--episodes", "an episode count or an existing .json.gz file")
    try:
        raw = source.read_bytes()
        text = gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw
        data = json.loads(text)
    except (OSError, EOFError, ValueError) as exc:
        raise InputError(source, "<file>", "gzip-compressed JSON (json.gz) or JSON", str(exc)) from None
    if not isinstance(data, dict) or not isinstance(data.get("episodes"), list):
        raise InputError(source, "episodes", "a top-level object with an 'episodes' list")
    _refuse_habitat_layout(source, data)
    if not data["episodes"]:
        raise InputError(source, "episodes", "a non-empty list of episodes", "[]")
    fields = Fields(source)
    episodes = [_parse_episode(fields, f"episodes[{i}]", item) for i, item in enumerate(data["episodes"])]
    _refuse_duplicates(source, episodes)
    return episodes


def _refuse_habitat_layout(source: Path, data: dict[str, Any]) -> None:
    """Habitat's ObjectNav v1 / HM3D-OVON datasets keep goals per category (``goals_by_category``) and, in a split
    file, the episodes in ``content/<scene>.json.gz`` beside it: the embedded world reads neither."""
    split_file = not data["episodes"] and (source.parent / "content").is_dir()
    if "goals_by_category" in data or split_file:
        field = "episodes" if split_file else "goals_by_category"
        got = "[] with content/ files beside it" if split_file else "goals by category, not in episodes"
        expected = (
            "the embedded world's layout; this is a Habitat ObjectNav / HM3D-OVON file: run it with --env habitat"
        )
        raise InputError(source, field, expected, got)


def _refuse_duplicates(source: Path, episodes: list[Episode]) -> None:
    first: dict[str, int] = {}
    for i, episode in enumerate(episodes):
        j = first.setdefault(episode.episode_id, i)
        if j != i:
            raise InputError(
                source,
                f"episodes[{i}].episode_id",
                f"an id no other episode has (episodes[{j}] has it)",
                episode.episode_id,
            )


def _vec3(fields: Fields, name: str, value: Any) -> Vec3:
    x, y, z = fields.numbers(value, name, 3)
    return (x, y, z)


def _quat(fields: Fields, name: str, value: Any) -> Quat:
    x, y, z, w = fields.numbers(value, name, 4)
    return (x, y, z, w)


def _identifier(fields: Fields, name: str, value: Any) -> str:
    """A non-empty string; integer ids (as some datasets write them) become strings."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return fields.text(value, name)


def _parse_episode(fields: Fields, name: str, item: Any) -> Episode:
    item = fields.mapping(item, name)
    goals = fields.sequence(item.get("goals"), f"{name}.goals", nonempty=True)
    return Episode(
        episode_id=_identifier(fields, f"{name}.episode_id", item.get("episode_id")),
        scene_id=_identifier(fields, f"{name}.scene_id", item.get("scene_id")),
        start_position=_vec3(fields, f"{name}.start_position", item.get("start_position")),
        start_rotation=_quat(fields, f"{name}.start_rotation", item.get("start_rotation")),
        object_category=_identifier(fields, f"{name}.object_category", item.get("object_category")),
        goals=tuple(_parse_goal(fields, f"{name}.goals[{k}]", g) for k, g in enumerate(goals)),
        info=fields.mapping(item.get("info", {}), f"{name}.info"),
    )


def _parse_goal(fields: Fields, name: str, item: Any) -> ObjectGoal:
    item = fields.mapping(item, name)
    view_points = []
    for k, point in enumerate(fields.sequence(item.get("view_points"), f"{name}.view_points", nonempty=True)):
        where = f"{name}.view_points[{k}]"
        state = fields.mapping(fields.mapping(point, where).get("agent_state"), f"{where}.agent_state")
        position = _vec3(fields, f"{where}.agent_state.position", state.get("position"))
        rotation = _quat(fields, f"{where}.agent_state.rotation", state.get("rotation"))
        view_points.append(ViewPoint(position, rotation, fields.number(point.get("iou", 1.0), f"{where}.iou")))
    return ObjectGoal(
        object_id=fields.integer(item.get("object_id", -1), f"{name}.object_id"),
        object_category=_identifier(fields, f"{name}.object_category", item.get("object_category", "object")),
        position=_vec3(fields, f"{name}.position", item.get("position")),
        view_points=tuple(view_points),
    )


GEODESIC_TOLERANCE = 0.10  # an episode's info.geodesic_distance may differ this much from the world's own


def validate_for_scenes(episodes: list[Episode], library: SceneLibrary, source: str | Path, sim: SimConfig) -> None:
    """Every episode fits the world: its scene is in ``library``, its start and view points are navigable, a goal
    is reachable from the start, and ``info.geodesic_distance`` (if given) is the world's within 10 %."""
    contexts: dict[str, SceneGoals] = {}
    for i, episode in enumerate(episodes):
        if episode.scene_id not in library:
            raise InputError(source, f"episodes[{i}].scene_id", f"a scene of --scenes {library.spec}", episode.scene_id)
        if episode.scene_id not in contexts:
            scene = library.load(episode.scene_id)
            reachable = largest_component(scene.navigable_grid(sim.agent_radius, sim.agent_height))
            contexts[episode.scene_id] = SceneGoals(scene, reachable, {})
        _validate_episode(episode, f"episodes[{i}]", contexts[episode.scene_id], source)


def _validate_episode(episode: Episode, name: str, context: SceneGoals, source: str | Path) -> None:
    grid, reachable = context.scene.grid, context.reachable
    where = f"a navigable position the agent can reach in {episode.scene_id}"

    def on_reachable(xy: tuple[float, float]) -> bool:
        cell = grid.world_to_cell(xy)
        return bool(grid.contains(cell) and reachable[cell[0], cell[1]])

    if not on_reachable(episode.start_xy):
        raise InputError(source, f"{name}.start_position", where, list(episode.start_position))
    for k, goal in enumerate(episode.goals):
        for m, point in enumerate(goal.view_points):
            if not on_reachable(point.xy):
                field = f"{name}.goals[{k}].view_points[{m}].agent_state.position"
                raise InputError(source, field, where, list(point.position))
    key = repr([point.position for goal in episode.goals for point in goal.view_points])  # episodes share goals
    context.goals.setdefault(key, list(episode.goals))
    distance = float(context.field_for(key).at(*episode.start_xy))
    if not math.isfinite(distance):
        raise InputError(source, f"{name}.goals", "a goal reachable from the start", "no view point reachable")
    given = episode.info.get("geodesic_distance")
    if isinstance(given, (int, float)) and abs(given - distance) > GEODESIC_TOLERANCE * distance:
        expected = f"the world's start-to-goal distance {distance:.2f} m within {GEODESIC_TOLERANCE:.0%}"
        raise InputError(source, f"{name}.info.geodesic_distance", expected, given)
