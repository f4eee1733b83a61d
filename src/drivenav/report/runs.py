"""The runs a report shows, read from their run directories (any world: embedded, Habitat or robot).

A run directory (``drivenav eval``, ``bench ablations``' ``runs/<method>/``) holds ``episodes.jsonl``, ``run.json``,
the copy of its episodes and one trace per episode; it is read and checked as a resume checks it
(:func:`drivenav.eval.rundir.read_run`). A run is named by its folder; two runs whose folders share a name are told
apart by their parent's name, then by a number. Its folder in the site is its name where that is a plain file name,
else a readable prefix and a hash of the name (:func:`~drivenav.eval.rundir.file_name`): no two runs share one.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from drivenav.analysis.ablation_data import MethodEntry
from drivenav.analysis.ablations import RUNS_DIR, method_entry
from drivenav.benchmarks.ovon_episodes import episode_splits
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.run_info import RunInfo
from drivenav.eval.rundir import file_name, read_run, trace_path
from drivenav.jsonstream import JsonObject
from drivenav.settings import section_defaults


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
        """The run's folder name inside the site (file-name safe; distinct names give distinct folders)."""
        return file_name(self.name)

    def stem(self, episode_id: str) -> str:
        """The file-name stem of an episode's files (its trace's, so that every world's ids fit)."""
        return trace_path(self.path, episode_id).stem

    def config(self) -> JsonObject:
        """``run.json``'s config tree, flattened to dotted keys (empty without ``run.json``)."""
        return {} if self.info is None else flatten(self.info.config_json())


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
    """A distinct name per run folder: its name, else ``parent-name``, else with ``-2``, ``-3``... appended; the
    parent of a ``bench ablations`` run is the folder above its ``runs/`` (``DIR/regimes/paper/runs/drive-nav``:
    ``paper-drive-nav``)."""
    names = [path.name or "run" for path in paths]
    names = [f"{_parent(p)}-{n}" if names.count(n) > 1 else n for p, n in zip(paths, names, strict=True)]
    seen: dict[str, int] = {}
    distinct = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        distinct.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    return distinct


def _parent(path: Path) -> str:
    """The name of the folder that tells runs of one name apart (above ``runs/``, where ``bench ablations`` keeps
    them)."""
    parent = path.parent
    return parent.parent.name if parent.name == RUNS_DIR and parent.parent.name else parent.name


def load_run(path: Path, name: str) -> Run:
    """The run in ``path``, checked (:func:`~drivenav.eval.rundir.read_run`): an :class:`InputError` when it has no
    ``episodes.jsonl`` or holds what a resume would refuse."""
    contents = read_run(path)
    records = tuple(sorted(contents.records, key=episode_order))
    episodes = {episode.episode_id: episode for episode in contents.episodes or ()}
    splits = episode_splits(list(episodes.values()))
    return Run(name, path, contents.info, records, episodes, splits, method_entry(list(records)))


def episode_order(record: EpisodeRecord) -> tuple[int, int, str, str]:
    """Numeric ids (ASCII digits) in number order, then the others by text (no id is converted to a number:
    ``'²'`` is a digit to Python, and a 5000-digit id is too long for ``int``)."""
    text = record.episode_id
    if text.isascii() and text.isdigit():
        number = text.lstrip("0")
        return 0, len(number), number, text
    return 1, 0, "", text


def compared_configs(runs: Sequence[Run]) -> list[JsonObject]:
    """Each run's flat settings as the runs are compared: a run records its own explorer's section only, so a key of
    another explorer's section that it lacks is that explorer's default (as earlier runs, which recorded every
    section, hold it; :func:`~drivenav.settings.section_defaults`)."""
    configs = [run.config() for run in runs]
    keys = sorted({key for config in configs for key in config})
    defaults = _explorer_defaults(keys)
    return [{**defaults, **config} for config in configs]


def config_differences(runs: Sequence[Run]) -> list[str]:
    """The dotted config keys whose values are not the same in every run (a key some runs lack differs), the runs
    compared as :func:`compared_configs` gives them."""
    configs = compared_configs(runs)
    keys = sorted({key for config in configs for key in config})
    return [key for key in keys if len({json.dumps(config.get(key), sort_keys=True) for config in configs}) > 1]


def _explorer_defaults(keys: Sequence[str]) -> JsonObject:
    """The installed explorers' default values of the dotted ``explorer.<key>.<field>`` keys among ``keys``."""
    wanted = set(keys)
    sections = {key.split(".")[1] for key in keys if key.startswith("explorer.") and key.count(".") >= 2}
    found: JsonObject = {}
    for section in sorted(sections):
        defaults = section_defaults(section)
        if defaults is not None:
            found.update(flatten(defaults, f"explorer.{section}."))
    return {key: value for key, value in found.items() if key in wanted}
