"""Habitat's episode layouts, read and written without habitat-lab: ObjectNav v1 and HM3D-OVON.

A split is ``{split}/{split}.json.gz`` (category maps, usually no episodes) plus ``{split}/content/<scene>.json.gz``
per scene: ``episodes`` without goals and ``goals_by_category``, keyed ``<scene basename>_<category>`` (the
basename of the episode's ``scene_id``, extension included). HM3D-OVON adds ``children_object_categories`` to
episodes (their instances count as goals too) and ``radius`` to view points, and leaves the category maps empty.

Episodes come back in habitat-lab's order (the split file's, then each content file in sorted order, each in file
order), with their goals resolved, as drivenav :class:`~drivenav.episode.Episode`\\ s. habitat-lab numbers a
file's episodes from 0 (overwriting ``episode_id``); drivenav keeps the file's own ``episode_id`` where there is
one, and where the ids of a split repeat across scenes, names every episode ``<scene>:<id>``.
"""

from __future__ import annotations

import gzip
import json
import os
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from drivenav.envs.habitat.benchmarks import LAYOUTS, OVON
from drivenav.episode import Episode, goal_to_dict, parse_episode, rounded
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.validation import Fields, read_json

CONTENT = "content"
CHILDREN = "children_object_categories"
DEFAULT_SCENE_PATH_PREFIX = "data/scene_datasets/"
CATEGORY_MAPS = ("category_to_task_category_id", "category_to_mp3d_category_id")


def goals_key(scene_id: str, category: str) -> str:
    """habitat-lab's key of a scene's goals of one category (``ObjectGoalNavEpisode.goals_key``)."""
    return f"{os.path.basename(scene_id)}_{category}"


def scene_name(scene_id: str) -> str:
    """A scene's short name: its basename without extensions (``.../TEEsavR23oF.basis.glb`` -> ``TEEsavR23oF``)."""
    return os.path.basename(scene_id).split(".", 1)[0]


def scene_path(scene_id: str, scenes_dir: str | None) -> str:
    """A scene id resolved as habitat-lab's readers resolve it: a leading ``data/scene_datasets/`` replaced by
    ``scenes_dir`` (habitat-lab's ``DEFAULT_SCENE_PATH_PREFIX``), else ``scenes_dir`` joined in front."""
    if scenes_dir is None:
        return scene_id
    if scene_id.startswith(DEFAULT_SCENE_PATH_PREFIX):
        scene_id = scene_id[len(DEFAULT_SCENE_PATH_PREFIX) :]
    return os.path.join(scenes_dir, scene_id)


def split_files(split_file: Path) -> list[Path]:
    """The files of a split in habitat-lab's reading order: the split file, then ``content/*.json.gz`` sorted."""
    content = split_file.parent / CONTENT
    scenes = sorted(p for p in content.glob("*.json.gz") if p.is_file()) if content.is_dir() else []
    return [split_file, *scenes]


def read_split(split_file: Path, layout: str) -> list[Episode]:
    """Every episode of a split, goals resolved (OVON: the children categories' instances included)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; expected one of {LAYOUTS}")
    if not split_file.is_file():
        raise InputError(split_file, "<document>", "a split file {split}/{split}.json.gz of the benchmark")
    episodes: list[Episode] = []
    for path in split_files(split_file):
        episodes.extend(_read_file(path, layout))
    if not episodes:
        raise InputError(split_file, "episodes", "at least one episode in the split or its content/ files", 0)
    return _unique_ids(episodes)


def _read_file(path: Path, layout: str) -> list[Episode]:
    fields = Fields(path)
    data = fields.mapping(read_json(path), "", required=("episodes",))
    items = fields.sequence(data["episodes"], "episodes")
    goals_by_category = fields.mapping(data.get("goals_by_category", {}), "goals_by_category")
    return [_read_episode(fields, i, item, goals_by_category, layout) for i, item in enumerate(items)]


def _read_episode(fields: Fields, index: int, item: Any, goals_by_category: JsonObject, layout: str) -> Episode:
    name = f"episodes[{index}]"
    item = dict(fields.mapping(item, name, required=("scene_id", "object_category")))
    scene_id = fields.text(item["scene_id"], f"{name}.scene_id")
    category = fields.text(item["object_category"], f"{name}.object_category")
    item.setdefault("episode_id", str(index))
    goals = list(item.get("goals") or [])
    if not goals:
        key = goals_key(scene_id, category)
        if key not in goals_by_category:
            raise fields.error("goals_by_category", f"the key '{key}' (episode {index}'s scene and category)")
        goals = list(goals_by_category[key])
        children = fields.texts(item.get(CHILDREN, []), f"{name}.{CHILDREN}") if layout == OVON else []
        for child in children:
            goals.extend(goals_by_category.get(goals_key(scene_id, child), []))
    item["goals"] = [_numeric_object_id(goal) for goal in goals]
    info = dict(item.get("info") or {})
    if item.get("scene_dataset_config"):
        info.setdefault("scene_dataset_config", item["scene_dataset_config"])
    item["info"] = info
    return parse_episode(fields, name, item)


def _numeric_object_id(goal: Any) -> Any:
    """Goal ids as integers (HM3D-OVON writes some as strings; a non-numeric id, '²' included, is kept out as -1)."""
    if isinstance(goal, dict) and isinstance(goal.get("object_id"), str):
        text = goal["object_id"]
        return {**goal, "object_id": int(text) if re.fullmatch("-?[0-9]{1,18}", text) else -1}
    return goal


def _unique_ids(episodes: list[Episode]) -> list[Episode]:
    counts = Counter(e.episode_id for e in episodes)
    if all(n == 1 for n in counts.values()):
        return episodes
    qualified = [replace(e, episode_id=f"{scene_name(e.scene_id)}:{e.episode_id}") for e in episodes]
    repeated = [name for name, n in Counter(e.episode_id for e in qualified).items() if n > 1]
    if repeated:
        raise InputError("episodes", "episode_id", "ids unique within each scene", repeated[0])
    return qualified


# ----------------------------------------------------------------------------------------------- writing


def write_split(episodes: Sequence[Episode], split_file: Path, layout: str) -> list[Path]:
    """Write ``episodes`` in a Habitat layout at ``split_file`` (``ROOT/{split}/{split}.json.gz``) and its
    ``content/`` folder; returns the files written (same bytes for the same episodes)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; expected one of {LAYOUTS}")
    categories = sorted({e.object_category for e in episodes})
    maps = {} if layout == OVON else {c: i for i, c in enumerate(categories)}
    written = [_write_json(split_file, {"episodes": [], **{key: maps for key in CATEGORY_MAPS}})]
    by_scene: dict[str, list[Episode]] = {}
    for episode in episodes:
        by_scene.setdefault(episode.scene_id, []).append(episode)
    for scene_id, scene_episodes in by_scene.items():
        path = split_file.parent / CONTENT / f"{scene_name(scene_id)}.json.gz"
        written.append(_write_json(path, _content(scene_episodes, layout)))
    return written


def _content(episodes: Iterable[Episode], layout: str) -> JsonObject:
    goals_by_category: dict[str, list[JsonObject]] = {}
    items = []
    for episode in episodes:
        key = goals_key(episode.scene_id, episode.object_category)
        goals = [goal_to_dict(goal) for goal in episode.goals]
        if goals_by_category.setdefault(key, goals) != goals:
            raise ValueError(f"episode {episode.episode_id}: other goals than an earlier episode under key {key}")
        item = {
            "episode_id": episode.episode_id,
            "scene_id": episode.scene_id,
            "start_position": rounded(episode.start_position),
            "start_rotation": rounded(episode.start_rotation),
            "object_category": episode.object_category,
            "goals": [],
            "info": dict(episode.info),
        }
        if layout == OVON:
            item[CHILDREN] = []
        items.append(item)
    return {"episodes": items, "goals_by_category": goals_by_category}


def _write_json(path: Path, payload: JsonObject) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(payload, separators=(",", ":"))
    with path.open("wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz:
        gz.write(text.encode())
    return path
