"""Habitat's episode layouts, read and written without habitat-lab: ObjectNav v1 and HM3D-OVON.

A split is ``{split}/{split}.json.gz`` (category maps, usually no episodes) plus ``{split}/content/<scene>.json.gz``
per scene: ``episodes`` without goals and ``goals_by_category``, keyed ``<scene basename>_<category>`` (the
basename of the episode's ``scene_id``, extension included). HM3D-OVON adds ``children_object_categories`` to
episodes (their instances count as goals too, kept under their own keys), ``radius`` to view points, goal ids as
text ``"<category>_<n>"``, and leaves the category maps empty. What is written is what HM3D-OVON's generator
writes (``naokiyokoyama/ovon``, ``ovon/dataset/objectnav_generator.py``, read for its shapes): every field of its
episodes and goals, floats to habitat-lab's 5 decimals, so a released file read and written again is unchanged,
and HM3D-OVON's own ``OVONDatasetV1`` reads an export. ``goals_by_category`` keys that no episode uses (as its own
category or a child) are not kept.

Episodes come back in habitat-lab's order (the split file's, then each content file in sorted order, each in file
order), with their goals resolved, as drivenav :class:`~drivenav.episode.Episode`\\ s. habitat-lab numbers a
file's episodes from 0 (overwriting ``episode_id``); drivenav keeps the file's own ``episode_id`` where there is
one, and where the ids of a split repeat across scenes, names every episode ``<scene>:<id>``; an export writes
such ids back as ``<id>`` only where they read back the same, else every id as it is. A name that still repeats is
refused naming the file it came from: an id twice in one scene, or two scenes of one base name in different folders
(``<scene>`` cannot tell them apart: the line an export gives for them). macOS metadata files
(``._<scene>.json.gz``, as HM3D-OVON's released ``train/content`` holds) are skipped with one warning.

Goals are written under the key of the episode's own text with that text as their category (a synonym
episode's goals too, as HM3D-OVON's released files have them); drivenav's own synonym episodes (``info.synonym``
with ``info.canonical_category``) read their goals back under the canonical category.
"""

from __future__ import annotations

import gzip
import json
import logging
import math
import os
import shutil
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any, NoReturn

from drivenav.envs.habitat.benchmarks import LAYOUTS, OVON
from drivenav.episode import (
    CHILDREN,
    Episode,
    ObjectGoal,
    coordinates,
    habitat_object_id,
    parse_episode,
    view_point_to_dict,
)
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.validation import Fields, read_json

log = logging.getLogger(__name__)

CONTENT = "content"
DEFAULT_SCENE_PATH_PREFIX = "data/scene_datasets/"
CATEGORY_MAPS = ("category_to_task_category_id", "category_to_mp3d_category_id")
OVON_CATEGORY_MAPS = ("category_to_task_category_id", "category_to_scene_annotation_category_id")  # left empty
APPLE_DOUBLE = "._"  # macOS metadata files beside the real ones (``._<scene>.json.gz``): not episodes
HABITAT_DIGITS = 5  # habitat-lab's DatasetFloatJSONEncoder writes floats with 5 decimals


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
    """The files of a split in habitat-lab's reading order: the split file, then ``content/*.json.gz`` sorted
    (macOS metadata files ``._*`` skipped, with one warning)."""
    content = split_file.parent / CONTENT
    found = sorted(p for p in content.glob("*.json.gz") if p.is_file()) if content.is_dir() else []
    skipped = tuple(p.name for p in found if p.name.startswith(APPLE_DOUBLE))
    if skipped:
        _warn_skipped(str(content), skipped)
    return [split_file, *(p for p in found if not p.name.startswith(APPLE_DOUBLE))]


@lru_cache(maxsize=16)
def _warn_skipped(folder: str, names: tuple[str, ...]) -> None:
    """One warning per folder and process (a split is read by the parent, each worker and the dataset class)."""
    log.warning("%s: skipped %d macOS metadata files (._*, not episodes), e.g. %s", folder, len(names), names[0])


def read_split(split_file: Path, layout: str) -> list[Episode]:
    """Every episode of a split, goals resolved (OVON: the children categories' instances included)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; expected one of {LAYOUTS}")
    if not split_file.is_file():
        raise InputError(split_file, "<document>", "a split file {split}/{split}.json.gz of the benchmark")
    episodes: list[Episode] = []
    files: list[Path] = []
    for path in split_files(split_file):
        read = _read_file(path, layout)
        episodes.extend(read)
        files.extend(path for _ in read)
    if not episodes:
        raise InputError(split_file, "episodes", "at least one episode in the split or its content/ files", 0)
    return _unique_ids(episodes, files)


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
    children = fields.texts(item.get(CHILDREN) or [], f"{name}.{CHILDREN}") if layout == OVON else []
    item[CHILDREN] = children
    if not item.get("goals"):
        key = goals_key(scene_id, category)
        if key not in goals_by_category:
            raise fields.error("goals_by_category", f"the key '{key}' (episode {index}'s scene and category)")
        canonical = _canonical_category(item.get("info"))
        goals = [_in_category(goal, category, canonical) for goal in _goals_of(fields, goals_by_category, key)]
        for child in children:
            child_key = goals_key(scene_id, child)
            goals.extend(_goals_of(fields, goals_by_category, child_key) if child_key in goals_by_category else [])
        item["goals"] = goals
    return parse_episode(fields, name, item)


def _goals_of(fields: Fields, goals_by_category: JsonObject, key: str) -> list[Any]:
    return fields.sequence(goals_by_category[key], f"goals_by_category.{key}")


def _canonical_category(info: Any) -> str | None:
    """The canonical category of drivenav's own synonym episodes (``info.synonym``, ``info.canonical_category``)."""
    if isinstance(info, dict) and info.get("synonym") is True and isinstance(info.get("canonical_category"), str):
        return str(info["canonical_category"])
    return None


def _in_category(goal: Any, text: str, canonical: str | None) -> Any:
    """A goal written under a synonym episode's text read back under the canonical category."""
    if canonical is not None and isinstance(goal, dict) and goal.get("object_category") == text:
        return {**goal, "object_category": canonical}
    return goal


def _unique_ids(episodes: list[Episode], files: Sequence[Path]) -> list[Episode]:
    """The episodes named as :func:`split_ids` names them; one name twice is refused (:func:`_refuse_repeated_name`,
    ``files``: the file each episode was read from)."""
    ids = split_ids([(e.scene_id, e.episode_id) for e in episodes])
    repeated = [name for name, n in Counter(ids).items() if n > 1]
    if repeated:
        _refuse_repeated_name(repeated[0], episodes, ids, files)
    if all(e.episode_id == i for e, i in zip(episodes, ids, strict=True)):
        return episodes
    return [replace(e, episode_id=i) for e, i in zip(episodes, ids, strict=True)]


def split_ids(held: Sequence[tuple[str, str]]) -> list[str]:
    """The ids :func:`read_split` gives the episodes of a split, from each one's scene and the id its file holds:
    the files' own ids where no two are alike, else every one named ``<scene>:<id>``."""
    ids = [episode_id for _, episode_id in held]
    if len(set(ids)) == len(ids):
        return ids
    return [f"{scene_name(scene_id)}:{episode_id}" for scene_id, episode_id in held]


# ----------------------------------------------------------------------------------------------- writing


def write_split(
    episodes: Sequence[Episode], split_file: Path, layout: str, source: str | Path = "episodes"
) -> list[Path]:
    """Write ``episodes`` in a Habitat layout at ``split_file`` (``ROOT/{split}/{split}.json.gz``) and its
    ``content/`` folder; returns the files written (same bytes for the same episodes). Scenes whose episodes would
    share a content file (one base name), or one scene and category with two sets of goals, are an
    :class:`InputError` naming ``source``."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; expected one of {LAYOUTS}")
    by_scene: dict[str, list[Episode]] = {}
    for episode in episodes:
        by_scene.setdefault(episode.scene_id, []).append(episode)
    names = _content_names(by_scene, source)
    ids = _file_ids(episodes, source)
    written = [_write_json(split_file, _split_payload(episodes, layout))]
    for scene_id, scene_episodes in by_scene.items():
        path = split_file.parent / CONTENT / f"{names[scene_id]}.json.gz"
        written.append(_write_json(path, _content(scene_episodes, ids, layout, source)))
    return written


def export_split(
    episodes: Sequence[Episode], folder: Path, layout: str, source: str | Path, overwrite: bool = False
) -> list[Path]:
    """Write ``episodes`` as the split in ``folder`` (``ROOT/{split}``: the split file and its ``content/``), whole
    or not at all: it is written beside ``folder`` and renamed into place once complete, so that no other export's
    content file is ever read with it. A ``folder`` holding anything is refused (an :class:`InputError` on
    ``--out`` naming it) unless ``overwrite``, which replaces an earlier export and nothing else."""
    _check_export_folder(folder, overwrite)
    staging, old = folder.with_name(f".{folder.name}.export"), folder.with_name(f".{folder.name}.replaced")
    for leftover in (staging, old):
        shutil.rmtree(leftover, ignore_errors=True)  # a killed export's: drivenav's own names
    written = write_split(episodes, staging / f"{folder.name}.json.gz", layout, source)
    if folder.exists():
        folder.rename(old)
    staging.rename(folder)
    shutil.rmtree(old, ignore_errors=True)
    return [folder / path.relative_to(staging) for path in written]


def _check_export_folder(folder: Path, overwrite: bool) -> None:
    """``folder`` is empty or missing, or (``overwrite``) holds only an export's files: the split file and
    ``content/*.json.gz``."""
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, "--out", "a folder for the split", "an existing file")
    held = sorted(p for p in folder.rglob("*") if not p.is_dir()) if folder.is_dir() else []
    if not held:
        return
    if not overwrite:
        expected = "a folder without an earlier export, or --overwrite to replace it (two exports never mix)"
        raise InputError(folder, "--out", expected, f"{len(held)} files, e.g. {held[0].relative_to(folder)}")
    exported = {folder / f"{folder.name}.json.gz", *(folder / CONTENT).glob("*.json.gz")}
    other = next((p for p in held if p not in exported), None)
    if other is not None:
        expected = "a folder holding only an earlier export (its split file and content/*.json.gz) to overwrite"
        raise InputError(folder, "--out", expected, str(other.relative_to(folder)))


def _file_ids(episodes: Sequence[Episode], source: str | Path) -> dict[tuple[str, str], str]:
    """The id each episode's content file holds, by scene and episode id: an id :func:`read_split` named
    ``<scene>:<id>`` written back as ``<id>`` where the split then reads back with the same ids (or where no form
    does: one id in several scenes), else every id as it is (``7`` and ``aws_small_house:7`` of one scene would
    otherwise both be ``'7'``). One id twice in a scene is an :class:`InputError` naming ``source``."""
    own = [e.episode_id for e in episodes]
    _refuse_repeated(episodes, source)
    stripped = [_file_episode_id(e) for e in episodes]
    reads_back = {
        form: split_ids([(e.scene_id, i) for e, i in zip(episodes, ids, strict=True)]) == own
        for form, ids in (("stripped", stripped), ("own", own))
    }
    unique = len({(e.scene_id, i) for e, i in zip(episodes, stripped, strict=True)}) == len(episodes)
    chosen = stripped if reads_back["stripped"] or (unique and not reads_back["own"]) else own
    return {(e.scene_id, e.episode_id): i for e, i in zip(episodes, chosen, strict=True)}


def _refuse_repeated_name(
    name: str, episodes: Sequence[Episode], ids: Sequence[str], files: Sequence[Path]
) -> NoReturn:
    """One :class:`InputError` naming the file of the second episode named ``name``: two scenes of one base name
    (``<scene>:<id>`` cannot tell them apart) are the export's line (:func:`_content_names`), one id twice in a
    scene is :func:`_refuse_repeated`'s."""
    (first, _), (second, file) = [(e, f) for e, i, f in zip(episodes, ids, files, strict=True) if i == name][:2]
    if first.scene_id != second.scene_id:
        _content_names([first.scene_id, second.scene_id], file)
    _refuse_repeated([first, second], file)
    raise InputError(file, "episode_id", "ids unique within each scene", name)


def _refuse_repeated(episodes: Sequence[Episode], source: str | Path) -> None:
    """One :class:`InputError` naming ``source`` and the id when one scene holds an id twice."""
    repeated = [held for held, n in Counter((e.scene_id, e.episode_id) for e in episodes).items() if n > 1]
    if repeated:
        scene_id, episode_id = repeated[0]
        raise InputError(source, "episode_id", "ids unique within each scene", f"{episode_id} twice in {scene_id}")


def _content_names(scene_ids: Iterable[str], source: str | Path) -> dict[str, str]:
    """Each scene's content file name (its base name without extensions), one per scene; two scenes of one base
    name are one :class:`InputError` naming ``source``."""
    names: dict[str, str] = {}
    for scene_id in scene_ids:
        name = scene_name(scene_id)
        other = next((s for s, n in names.items() if n == name), None)
        if other is not None:
            expected = f"scenes with distinct base names (each scene's episodes go to content/{name}.json.gz)"
            raise InputError(source, "scene_id", expected, f"{other} and {scene_id}")
        names[scene_id] = name
    return names


def _split_payload(episodes: Sequence[Episode], layout: str) -> JsonObject:
    """The split file: HM3D-OVON's holds nothing; ObjectNav v1's the category maps (one id per category)."""
    if layout == OVON:
        return {"goals_by_category": {}, "episodes": []}
    maps = {c: i for i, c in enumerate(sorted({e.object_category for e in episodes}))}
    return {"episodes": [], **{key: maps for key in CATEGORY_MAPS}}


def _content(
    episodes: Iterable[Episode], ids: Mapping[tuple[str, str], str], layout: str, source: str | Path
) -> JsonObject:
    goals_by_category: dict[str, list[JsonObject]] = {}
    items = []
    for episode in episodes:
        for key, goals in _keyed_goals(episode, layout).items():
            if goals_by_category.setdefault(key, goals) != goals:
                expected = f"the same goals in every episode of one scene and category (key {key})"
                raise InputError(source, "goals", expected, f"other goals in episode {episode.episode_id}")
        items.append(_episode_item(episode, ids[episode.scene_id, episode.episode_id], layout))
    if layout == OVON:
        return {"goals_by_category": goals_by_category, "episodes": items, **{k: {} for k in OVON_CATEGORY_MAPS}}
    return {"episodes": items, "goals_by_category": goals_by_category}


def _keyed_goals(episode: Episode, layout: str) -> dict[str, list[JsonObject]]:
    """An episode's goals by key: a child category's under its own key (HM3D-OVON), every other goal under the
    episode's text, in that category."""
    children = set(episode.children_object_categories if layout == OVON else ()) - {episode.object_category}
    keyed: dict[str, list[JsonObject]] = {goals_key(episode.scene_id, episode.object_category): []}
    for goal in episode.goals:
        category = goal.object_category if goal.object_category in children else episode.object_category
        keyed.setdefault(goals_key(episode.scene_id, category), []).append(_goal_item(goal, category, layout))
    return keyed


def _goal_item(goal: ObjectGoal, category: str, layout: str) -> JsonObject:
    """A goal as the layout writes it: HM3D-OVON's text id and view point radii, ObjectNav v1's integer id."""
    position = coordinates(goal.position, HABITAT_DIGITS)
    if layout == OVON:
        points = [view_point_to_dict(vp, HABITAT_DIGITS) for vp in goal.view_points]
        return {"object_category": category, "object_id": habitat_object_id(goal), "position": position,
                "view_points": points}  # fmt: skip
    points = [view_point_to_dict(replace(vp, radius=None), HABITAT_DIGITS) for vp in goal.view_points]
    return {"object_id": goal.object_id, "object_category": category, "position": position, "view_points": points}


def _episode_item(episode: Episode, file_id: str, layout: str) -> JsonObject:
    """An episode without its goals: HM3D-OVON's every field (habitat-lab's ``Episode`` ones included), ObjectNav
    v1's as before plus ``scene_dataset_config``."""
    start = {
        "start_position": coordinates(episode.start_position, HABITAT_DIGITS),
        "start_rotation": coordinates(episode.start_rotation, HABITAT_DIGITS),
    }
    info = _with_euclidean_distance(episode)
    head = {"episode_id": file_id, "scene_id": episode.scene_id}
    if layout != OVON:
        return {**head, **start, "object_category": episode.object_category, "goals": [], "info": info,
                "scene_dataset_config": episode.scene_dataset_config}  # fmt: skip
    return {
        **head,
        "scene_dataset_config": episode.scene_dataset_config,
        "additional_obj_config_paths": [],
        **start,
        "info": info,
        "goals": [],
        "start_room": None,
        "shortest_paths": None,
        "object_category": episode.object_category,
        CHILDREN: list(episode.children_object_categories),
    }


def _file_episode_id(episode: Episode) -> str:
    """The id a content file holds: an id :func:`read_split` named ``<scene>:<id>`` written back as ``<id>``."""
    prefix = f"{scene_name(episode.scene_id)}:"
    return episode.episode_id[len(prefix) :] if episode.episode_id.startswith(prefix) else episode.episode_id


def _with_euclidean_distance(episode: Episode) -> JsonObject:
    """``info`` with ``euclidean_distance`` (HM3D-OVON's statistics read it) where it has none: the straight-line
    distance from the start to the nearest view point. HM3D-OVON's generator measures it to the view point its
    shortest path ends at, which is never nearer; drivenav's episodes do not record that one."""
    info = dict(episode.info)
    points = [vp.position for goal in episode.goals for vp in goal.view_points]
    if "euclidean_distance" not in info and points:
        nearest = min(math.dist(episode.start_position, point) for point in points)
        info["euclidean_distance"] = round(nearest, HABITAT_DIGITS)
    return info


def _write_json(path: Path, payload: JsonObject) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(payload, separators=(",", ":"))
    with path.open("wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz:
        gz.write(text.encode())
    return path
