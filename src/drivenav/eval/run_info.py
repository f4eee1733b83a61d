"""``run.json``: what a run was started with -- its resolved settings, its world, the episodes' digest and where
the code came from -- as a typed :class:`RunInfo`.

On disk, ``config`` is one JSON tree: the world's recipe under ``config.env`` (``name`` and the fields of its
:class:`~drivenav.envs.base.EnvSpec`) beside the sections of :func:`~drivenav.settings.settings_to_dict`. Reading
it back rebuilds :class:`~drivenav.settings.Settings` through the same checks as ``--config``, so a hand-edited
``run.json`` with a wrong key, type or value is one :class:`~drivenav.errors.InputError` naming ``config.KEY``.
The world stays JSON: each world's recipe has its own fields, and only its name and scenes are ever read back.

A run of a plug-in explorer records beside ``config`` which entry point and distribution provided it
(``explorer_plugin``: ``name``, ``value``, ``distribution``), so that once the plug-in is uninstalled a resume of the
run is refused in one line naming what to install (:func:`~drivenav.settings.missing_explorer`), while its readers
(a report, ``compare``, pictures) still read it, its settings tree kept as recorded. The sections of explorers other
than the chosen one, which a ``run.json`` of an older drivenav holds, are dropped on reading and left out of the
resume's comparison (:func:`~drivenav.settings.held_sections_only`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from drivenav.agent.explorers import DEFAULT_EXPLORER
from drivenav.envs.base import EnvSpec
from drivenav.errors import InputError
from drivenav.jsonstream import DOCUMENT, JsonObject
from drivenav.plugins import Declared
from drivenav.settings import (
    RunSettings,
    Settings,
    default_settings,
    first_difference,
    held_sections_only,
    settings_from_dict,
    settings_to_dict,
    uninstalled_explorer,
)

WORLD_KEY = "env"  # the key of the world's recipe in run.json's config
PLUGIN_KEY = "explorer_plugin"  # the key of a plug-in explorer's entry point in run.json


def world_json(env: EnvSpec) -> JsonObject:
    """A world's recipe as ``run.json`` records it: its ``--env`` name and its fields, in JSON's own types (a
    tuple is a list), so that it compares equal to the tree read back on resume."""
    tree: JsonObject = json.loads(json.dumps({"name": env.name, **asdict(env)}))
    return tree


@dataclass(frozen=True)
class RunInfo:
    """``run.json``: the run's settings and world, the sha256 of its episodes, the drivenav version, the git
    commit of the checkout and whether its tree was dirty (None outside git), and the entry point of its explorer
    when a plug-in provided it (None for drivenav's own)."""

    config: Settings
    world: JsonObject
    episodes_sha256: str
    version: str
    git_commit: str | None
    git_dirty: bool | None
    explorer_plugin: Declared | None = None
    recorded: JsonObject | None = None

    @property
    def agent(self) -> str:
        """The run's agent (``config.run.agent``; an uninstalled plug-in's as recorded): the agent every record of
        the run names (:func:`~drivenav.eval.records.check_agent`)."""
        run = (self.recorded or {}).get("run")
        recorded = run.get("agent") if isinstance(run, dict) else None
        return recorded if isinstance(recorded, str) else self.config.run.agent

    def config_json(self) -> JsonObject:
        """``run.json``'s ``config`` tree: the world under ``env`` beside the settings' sections (as recorded, for a
        run read back whose explorer is not installed)."""
        sections = settings_to_dict(self.config) if self.recorded is None else self.recorded
        tree: JsonObject = json.loads(json.dumps({WORLD_KEY: self.world, **sections}))
        return tree

    def to_json(self) -> JsonObject:
        """The ``run.json`` object (``explorer_plugin`` only for a plug-in's run)."""
        tree: JsonObject = {
            "config": self.config_json(),
            "episodes_sha256": self.episodes_sha256,
            "version": self.version,
            "git_commit": self.git_commit,
            "git_dirty": self.git_dirty,
        }
        plugin = self.explorer_plugin
        if plugin is not None:
            tree[PLUGIN_KEY] = {"name": plugin.name, "value": plugin.value, "distribution": plugin.source}
        return tree

    @staticmethod
    def from_json(data: object, source: str | Path, reading: bool = False) -> RunInfo:
        """A ``run.json`` read back, its settings rebuilt and checked; anything else is one :class:`InputError`
        naming the field (``config.sim.max_steps``, ``episodes_sha256``). A run whose explorer is not installed is
        refused (:func:`~drivenav.settings.missing_explorer`) unless only ``reading`` it (a report, ``compare``, a
        picture): then its tree is kept as recorded (``recorded``) and ``config`` holds the rest of its settings."""
        if not isinstance(data, dict):
            raise InputError(source, DOCUMENT, "a JSON object", type(data).__name__)
        config = _object(data, "config", source)
        world = _object(config, WORLD_KEY, source, "config.")
        tree = {key: value for key, value in config.items() if key != WORLD_KEY}
        plugin = explorer_plugin(data, source)
        recorded = tree if reading and uninstalled_explorer(tree) is not None else None
        try:
            settings = settings_from_dict(tree if recorded is None else _without_explorer(tree), plugin)
        except InputError as error:
            raise InputError(source, f"config.{error.field}", error.expected, error.got) from None
        return RunInfo(
            settings,
            world,
            _text(data, "episodes_sha256", source),
            _text(data, "version", source),
            _optional_text(data, "git_commit", source),
            _optional_flag(data, "git_dirty", source),
            plugin,
            recorded,
        )

    def check_resume(self, previous: JsonObject, source: str | Path) -> None:
        """Refuse to resume a run started with other settings or episodes (``previous``: the directory's
        ``run.json``). Its settings are rebuilt first (a hand-edited value is named as such); the trees are then
        compared as written, so that a key one of them lacks (a ``run.json`` of another drivenav version) is a
        difference, unless it is a setting added since and left at its default here (the behaviour its absence
        had: a long grid resumes across a version that adds a setting)."""
        RunInfo.from_json(previous, source)
        defaults = json.loads(json.dumps(settings_to_dict(default_settings(self.config))))
        key = first_difference(held_sections_only(previous["config"]), self.config_json(), defaults)
        if key is not None:
            raise InputError(
                source, f"config.{key}", "the settings this run directory was started with, to resume it", "others"
            )
        if previous["episodes_sha256"] != self.episodes_sha256:
            raise InputError(source, "episodes", "the episodes this run directory was started with, to resume it")


def _without_explorer(tree: JsonObject) -> JsonObject:
    """``tree`` with the default explorer and agent in place of an uninstalled plug-in's (its other sections kept)."""
    run = tree.get("run")
    run_section = {**run, "agent": RunSettings.agent} if isinstance(run, dict) else run
    return {**tree, "explorer": {"name": DEFAULT_EXPLORER}, "run": run_section}


def explorer_plugin(data: JsonObject, source: str | Path) -> Declared | None:
    """The entry point ``run.json`` (``data``) records for its plug-in explorer (None: drivenav's own, or a run of an
    older drivenav); a record not as drivenav writes it is one :class:`InputError`."""
    record = data.get(PLUGIN_KEY)
    if record is None:
        return None
    plugin = _object(data, PLUGIN_KEY, source)
    fields = [_text(plugin, key, source, f"{PLUGIN_KEY}.") for key in ("name", "value", "distribution")]
    return Declared(*fields)


def _object(data: JsonObject, key: str, source: str | Path, prefix: str = "") -> JsonObject:
    value = data.get(key)
    if not isinstance(value, dict):
        raise InputError(source, f"{prefix}{key}", "a JSON object as drivenav writes it", value)
    return value


def _text(data: JsonObject, key: str, source: str | Path, prefix: str = "") -> str:
    value = data.get(key)
    if not isinstance(value, str):
        raise InputError(source, f"{prefix}{key}", "a string as drivenav writes it", value)
    return value


def _optional_text(data: JsonObject, key: str, source: str | Path) -> str | None:
    return None if data.get(key) is None else _text(data, key, source)


def _optional_flag(data: JsonObject, key: str, source: str | Path) -> bool | None:
    value = data.get(key)
    if value is not None and not isinstance(value, bool):
        raise InputError(source, key, "true, false or null", value)
    return value
