"""The runs a report shows, read from their run directories (any world: embedded, Habitat or robot).

A run directory (``drivenav eval``, ``bench ablations``' ``runs/<method>/``) holds ``episodes.jsonl``, ``run.json``,
the copy of its episodes and one trace per episode. A run is named by its folder; two runs whose folders share a
name are told apart by their parent's name, then by a number.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.ablation_data import MethodEntry
from drivenav.eval.ablations import method_entry
from drivenav.eval.episodes import load_episodes
from drivenav.eval.ovon_episodes import episode_splits
from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.run_info import RunInfo
from drivenav.eval.rundir import EPISODES_COPY, EPISODES_FILE, RUN_FILE, trace_path
from drivenav.jsonstream import JsonObject


@dataclass(frozen=True)
class Run:
    """One run: its name and folder, ``run.json`` (None when the folder has none), its records in episode order,
    its episodes by id (empty without the copy), each episode's split (benchmark v2) and its aggregate."""

    name: str
    path: Path
    info: RunInfo | None
    records: tuple[EpisodeRecord, ...]
    episodes: dict[str, Episode]
    splits: dict[str, str]
    entry: MethodEntry

    @property
    def slug(self) -> str:
        """The run's folder name inside the site (file-name safe, unique among the report's runs)."""
        return _safe(self.name)

    def stem(self, episode_id: str) -> str:
        """The file-name stem of an episode's files (its trace's, so that every world's ids fit)."""
        return trace_path(self.path, episode_id).stem

    def config(self) -> JsonObject:
        """``run.json``'s config tree, flattened to dotted keys (empty without ``run.json``)."""
        return {} if self.info is None else flatten(self.info.config_json())


def _safe(name: str) -> str:
    return "".join(ch if ch.isascii() and (ch.isalnum() or ch in "-_.") else "_" for ch in name).strip(".") or "run"


def flatten(tree: JsonObject, prefix: str = "") -> JsonObject:
    """Nested objects joined by dots (lists stay values)."""
    flat: JsonObject = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def run_names(paths: Sequence[Path]) -> list[str]:
    """A distinct name per run folder: its name, else ``parent/name``, else with ``-2``, ``-3``... appended."""
    names = [path.name or "run" for path in paths]
    names = [f"{p.parent.name}-{n}" if names.count(n) > 1 else n for p, n in zip(paths, names, strict=True)]
    seen: dict[str, int] = {}
    distinct = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        distinct.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    return distinct


def load_run(path: Path, name: str) -> Run:
    """The run in ``path``: an :class:`InputError` when it has no ``episodes.jsonl``."""
    results = path / EPISODES_FILE
    if not results.is_file():
        raise InputError(
            path, "RUN", "a run directory (episodes.jsonl written by 'drivenav eval')", "no episodes.jsonl"
        )
    records = tuple(sorted(read_records(results), key=_episode_order))
    episodes = _episodes(path / EPISODES_COPY)
    info = _info(path / RUN_FILE)
    splits = episode_splits(list(episodes.values()))
    return Run(name, path, info, records, episodes, splits, method_entry(list(records)))


def _episode_order(record: EpisodeRecord) -> tuple[int, str]:
    """Numeric ids in number order, then the others by text."""
    text = record.episode_id
    return (int(text), "") if text.isdigit() else (1 << 62, text)


def _episodes(path: Path) -> dict[str, Episode]:
    if not path.is_file():
        return {}
    return {episode.episode_id: episode for episode in load_episodes(path, require_goals=False)}


def _info(path: Path) -> RunInfo | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError:
        raise InputError(path, "run.json", "the JSON drivenav wrote") from None
    return RunInfo.from_json(data, path)


def config_differences(runs: Sequence[Run]) -> list[str]:
    """The dotted config keys whose values are not the same in every run (a key some runs lack differs)."""
    configs = [run.config() for run in runs]
    keys = sorted({key for config in configs for key in config})
    return [key for key in keys if len({json.dumps(config.get(key), sort_keys=True) for config in configs}) > 1]
