"""Plug-in explorers in the settings and in ``run.json``: only the chosen explorer's section is in a run's settings,
so whatever is installed -- a plug-in with a hyphen, a keyword or ``name`` for a name, a config that cannot be a
section, rules or a ``__post_init__`` that raise -- the built-in methods' ``config show`` and ``eval`` keep working
and choosing the plug-in is one line naming it and its package. Its section's declared ranges are checked at load;
a run of an explorer that is no longer installed is refused in one line naming what to install, and a run written
when every installed explorer had a section still reads and resumes."""

from __future__ import annotations

import json
import logging
import pickle
from pathlib import Path
from typing import Any

import pytest

from conftest import plug_in
from drivenav.agent.explorers import EXPLORERS, settings_key
from drivenav.agents import make_agent, warn_shadowed_explorers
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.errors import InputError
from drivenav.eval.run_info import RunInfo, world_json
from drivenav.plugins import Declared
from drivenav.settings import (
    explorer_section,
    load_settings,
    section_defaults,
    settings_from_dict,
    settings_to_dict,
    settings_to_yaml,
)

DATA = Path(__file__).parent / "data"
GROUP = "drivenav.explorers"
DIST = "hostile-explorers"

MODULE = """
from dataclasses import dataclass, field
from typing import ClassVar

from drivenav.agent.config import ExplorerEntry
from drivenav.agent.explorers.greedy.config import GreedyConfig
from drivenav.ranges import LENGTH

GREEDY = "drivenav.agent.explorers.greedy.explorer:GreedyExplorer"


@dataclass(frozen=True)
class Fine(GreedyConfig):
    reach: float = 1.0
    time_offset: float = 0.0
    RANGES: ClassVar = {**GreedyConfig.RANGES, "reach": LENGTH}


class NotADataclass:
    reach = 1.0


@dataclass(frozen=True)
class NoDefault:
    reach: float


@dataclass(frozen=True)
class ASet:
    cells: set[int] = field(default_factory=set)


class Custom:
    pass


@dataclass(frozen=True)
class ACustomClass:
    thing: Custom = field(default_factory=Custom)


@dataclass(frozen=True)
class RaisesOnSet(GreedyConfig):
    reach: float = 1.0

    def __post_init__(self):
        if self.reach != 1.0:
            raise SystemExit("reach is fixed")


@dataclass(frozen=True)
class InterruptsAtDefaults:
    reach: float = 1.0

    def __post_init__(self):
        raise KeyboardInterrupt


def raising_rules(config, sim):
    raise RuntimeError("no rules today")


def entry(name, config, rules=None):
    extra = () if rules is None else (rules,)
    return ExplorerEntry(name, config, GREEDY, "a hostile explorer", ("agent.enrich=false",), *extra)


MY_EXPLORER = entry("my-explorer", Fine)
MY_DOT_EXPLORER = entry("my.explorer", Fine)
CLASS = entry("class", Fine)
NAME = entry("name", Fine)
ORACLE = entry("oracle", Fine)
NOT_A_DATACLASS = entry("not-a-dataclass", NotADataclass)
NO_DEFAULT = entry("no-default", NoDefault)
A_SET = entry("a-set", ASet)
A_CUSTOM_CLASS = entry("a-custom-class", ACustomClass)
RAISING_RULES = entry("raising-rules", Fine, raising_rules)
RAISES_ON_SET = entry("raises-on-set", RaisesOnSet)
INTERRUPTS = entry("interrupts", InterruptsAtDefaults)
"""

WORKING = {"my-explorer": "my_explorer", "class": "class_", "name": "name_"}
"""Plug-ins whose names are no identifiers, or are keywords, or ``name``: normal, they work under their keys."""

BROKEN = {
    "not-a-dataclass": "not a dataclass",
    "no-default": "TypeError",
    "a-set": "ValidationError",
    "a-custom-class": "ValidationError",
    "raising-rules": "no rules today",
    "interrupts": "KeyboardInterrupt",
    "my.explorer": "explorer.my_explorer, which explorer 'my-explorer' holds",
}
"""Plug-ins that cannot be configured, and what their one line says."""


def _attribute(name: str) -> str:
    return name.replace("-", "_").replace(".", "_dot_").upper()


@pytest.fixture
def hostile(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Every plug-in of :data:`MODULE` installed at once (entry points of the distribution :data:`DIST`)."""
    (tmp_path / "hostile_explorers.py").write_text(MODULE, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    names = [*WORKING, *BROKEN, "raises-on-set", "oracle"]
    points = [(GROUP, name, f"hostile_explorers:{_attribute(name)}", DIST) for name in names]
    points[names.index("my.explorer")] = (GROUP, "my.explorer", "hostile_explorers:MY_DOT_EXPLORER", DIST)
    plug_in(monkeypatch, *points)


@pytest.mark.parametrize(
    ("name", "key"),
    [
        ("directions", "directions"),
        ("apexnav", "apexnav"),
        ("my-explorer", "my_explorer"),
        ("a.b", "a_b"),
        ("class", "class_"),
        ("None", "None_"),
        ("name", "name_"),
        ("3d", "x3d"),
        ("_private", "x_private"),
        ("", "x"),
        ("__init__", "x__init__"),
        ("café", "caf_"),
    ],
)
def test_any_entry_point_name_maps_to_an_identifier_key(name: str, key: str) -> None:
    assert settings_key(name) == key and key.isidentifier()


def test_the_settings_hold_the_chosen_explorers_section_only() -> None:
    for method, key in (("drive-nav", "directions"), ("vlfm", "vlfm"), ("apexnav", "apexnav")):
        tree = settings_to_dict(load_settings(method))["explorer"]
        assert set(tree) == {"name", key}, tree


def test_a_key_of_an_unchosen_explorer_is_refused_in_one_line() -> None:
    with pytest.raises(InputError) as caught:
        load_settings("drive-nav", overrides=["explorer.vlfm.keep_radius=0.4"])
    assert caught.value.field == "explorer.vlfm" and "--set explorer.name=vlfm" in caught.value.expected
    chosen = load_settings("drive-nav", overrides=["explorer.name=vlfm", "explorer.vlfm.keep_radius=0.4"])
    assert explorer_section(chosen, "vlfm").keep_radius == 0.4  # type: ignore[attr-defined]


@pytest.mark.usefixtures("hostile")
@pytest.mark.parametrize("method", ["drive-nav", "apexnav", "vlfm"])
def test_config_show_of_a_built_in_method_works_whatever_is_installed(
    method: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["config", "show", "--agent", method]) == 0
    shown = capsys.readouterr()
    assert "hostile" not in shown.out + shown.err


@pytest.mark.usefixtures("hostile")
def test_eval_of_a_built_in_method_works_whatever_is_installed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    args = ["eval", "--agent", "drive-nav", "--scenes", "procedural:1", "--episodes", "1", "--max-steps", "30"]
    assert main([*args, "--out", str(out)]) == 0, capsys.readouterr().err
    written = json.loads((out / "run.json").read_text(encoding="utf-8"))
    assert set(written["config"]["explorer"]) == {"name", "directions"} and "explorer_plugin" not in written


@pytest.mark.usefixtures("hostile")
@pytest.mark.parametrize(("name", "key"), sorted(WORKING.items()))
def test_a_plugin_of_any_name_is_configured_under_its_key(name: str, key: str) -> None:
    settings = load_settings(name, overrides=[f"explorer.{key}.reach=2.5"])
    assert settings.explorer.name == name and explorer_section(settings, name).reach == 2.5  # type: ignore[attr-defined]
    assert set(settings_to_dict(settings)["explorer"]) == {"name", key}
    assert pickle.loads(pickle.dumps(settings)) == settings  # to workers and Ray
    assert settings_from_dict(settings_to_dict(settings)) == settings  # run.json's round trip


@pytest.mark.usefixtures("hostile")
def test_config_show_of_a_plugin_loads_back(tmp_path: Path) -> None:
    settings = load_settings("my-explorer", overrides=["explorer.my_explorer.reach=2.5"])
    saved = tmp_path / "shown.yaml"
    saved.write_text(settings_to_yaml(settings), encoding="utf-8")
    assert "  my_explorer:\n" in saved.read_text() and load_settings(configs=[str(saved)]) == settings


@pytest.mark.usefixtures("hostile")
@pytest.mark.parametrize(("name", "words"), sorted(BROKEN.items()))
def test_choosing_a_plugin_that_cannot_be_configured_is_one_line(
    name: str, words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    for args in (["--agent", name], ["--set", f"explorer.name={name}"]):
        assert main(["config", "show", *args]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert f"plug-in {name}" in err and DIST in err and words in err, err


@pytest.mark.usefixtures("hostile")
def test_a_section_whose_post_init_raises_on_set_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "show", "--agent", "raises-on-set"]) == 0
    capsys.readouterr()
    assert main(["config", "show", "--agent", "raises-on-set", "--set", "explorer.raises_on_set.reach=2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "plug-in raises-on-set" in err and "SystemExit: reach is fixed" in err, err


@pytest.mark.usefixtures("hostile")
@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("reach=-5", "expected a finite number in [0, 1000] (metres), got -5.0"),
        ("min_goal_distance=1e9", "expected a finite number in [0, 1000] (metres)"),
        ("time_offset=nan", "expected a finite number, got nan"),
    ],
)
def test_a_plugin_sections_declared_ranges_are_checked_at_load(setting: str, words: str) -> None:
    with pytest.raises(InputError) as caught:
        load_settings("my-explorer", overrides=[f"explorer.my_explorer.{setting}"])
    key = setting.partition("=")[0]
    assert caught.value.field == f"explorer.my_explorer.{key}" and words in str(caught.value), caught.value
    assert load_settings("my-explorer", overrides=["explorer.my_explorer.time_offset=-5"])  # no range: any number


def test_a_plugin_explorer_named_as_a_reference_agent_is_warned_of(
    hostile: None, caplog: pytest.LogCaptureFixture
) -> None:
    warn_shadowed_explorers.cache_clear()
    with caplog.at_level(logging.WARNING):
        make_agent(load_settings("oracle"))
    warn_shadowed_explorers.cache_clear()
    lines = [r.getMessage() for r in caplog.records if "oracle" in r.getMessage()]
    assert len(lines) == 1 and DIST in lines[0] and "--set explorer.name=oracle" in lines[0], lines


def _old_run() -> dict[str, Any]:
    data: dict[str, Any] = json.loads((DATA / "run-all-explorers.json").read_text(encoding="utf-8"))
    return data


def test_a_run_json_with_every_installed_explorers_section_still_reads_and_resumes() -> None:
    """Written before: every installed explorer's section, a plug-in's (``pocket``) since uninstalled among them."""
    old = _old_run()
    assert "pocket" in old["config"]["explorer"]
    info = RunInfo.from_json(old, "run.json")
    assert info.config == RunInfo.from_json(json.loads((DATA / "run.json").read_text()), "run.json").config
    now = RunInfo(info.config, world_json(EmbeddedSpec("procedural:3", 3)), old["episodes_sha256"], "v", None, None)
    now.check_resume(old, "run.json")


def _pocket_run(record: bool) -> dict[str, Any]:
    data = _old_run()
    data["config"]["explorer"]["name"] = "pocket"
    data["config"]["run"]["agent"] = "pocket"
    if record:
        data["explorer_plugin"] = {
            "name": "pocket",
            "value": "pocket_nav.config:EXPLORER",
            "distribution": "pocket-nav",
        }
    return data


@pytest.mark.parametrize(
    ("record", "words"),
    [
        (True, "install the package pocket-nav, which provides entry point drivenav.explorers: pocket = 'pocket_nav"),
        (False, "install a package providing entry point drivenav.explorers: pocket"),
    ],
)
def test_a_run_whose_explorer_is_not_installed_is_refused_naming_what_to_install(
    record: bool, words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(InputError) as caught:
        RunInfo.from_json(_pocket_run(record), "run.json")
    assert caught.value.field == "config.explorer.name" and words in str(caught.value), caught.value
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.json").write_text(json.dumps(_pocket_run(record)), encoding="utf-8")
    assert main(["eval", "--agent", "pocket", "--scenes", "procedural:3", "--episodes", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err


def test_a_plugin_run_records_its_entry_point_and_reads_back(hostile: None) -> None:
    settings = load_settings("my-explorer")
    plugin = EXPLORERS.declared["my-explorer"]
    info = RunInfo(settings, world_json(EmbeddedSpec("procedural:3", 3)), "x", "v", None, None, plugin)
    written = info.to_json()
    assert written["explorer_plugin"] == {
        "name": "my-explorer",
        "value": "hostile_explorers:MY_EXPLORER",
        "distribution": DIST,
    }
    assert RunInfo.from_json(json.loads(json.dumps(written)), "run.json") == info
    assert plugin == Declared("my-explorer", "hostile_explorers:MY_EXPLORER", DIST)


def test_a_config_file_with_every_explorers_default_section_still_loads(tmp_path: Path) -> None:
    """A file an older ``config show`` wrote held every installed explorer's section: those at their defaults are
    dropped; one set otherwise is refused in one line."""
    tree = settings_to_dict(load_settings("drive-nav"))
    tree["explorer"].update({key: section_defaults(key) for key in ("greedy", "vlfm", "apexnav")})
    older = tmp_path / "older.yaml"
    older.write_text(json.dumps(tree), encoding="utf-8")  # JSON is YAML
    assert load_settings("drive-nav", configs=[str(older)]) == load_settings("drive-nav")
    tree["explorer"]["vlfm"]["min_goal_distance"] += 1.0
    older.write_text(json.dumps(tree), encoding="utf-8")
    with pytest.raises(InputError, match=r"explorer\.vlfm"):
        load_settings("drive-nav", configs=[str(older)])
