"""Explorers on one agent body: the registry (built-ins as declared in pyproject.toml, plug-ins by entry point, a
broken plug-in as one line that leaves the built-ins working), each method's explorer and settings section, the
counters each explorer writes into its records, and no dispatch on method or explorer names in the code."""

from __future__ import annotations

import math
import re
from importlib.metadata import EntryPoint
from pathlib import Path
from types import SimpleNamespace

import pytest
import tomllib

from agent_scenes import episode_for, t_junction
from drivenav import plugins
from drivenav.agent.config import ExplorerEntry
from drivenav.agent.explorers import BUILT_IN_EXPLORERS, EXPLORERS
from drivenav.agents import make_agent
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.errors import InputError
from drivenav.eval.runner import run_episode
from drivenav.methods import METHOD_NAMES, METHODS, REFERENCE_AGENTS
from drivenav.plugins import Registry
from drivenav.settings import explorer_section, load_settings, settings_from_dict, settings_to_dict
from drivenav.types import SimConfig

ROOT = Path(__file__).parents[1]
SOURCE = ROOT / "src" / "drivenav"
SIM = SimConfig()


def test_the_built_in_explorers_are_declared_in_pyproject_as_plugins_declare_theirs() -> None:
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    assert declared["drivenav.explorers"] == BUILT_IN_EXPLORERS
    for name in BUILT_IN_EXPLORERS:
        entry = EXPLORERS.get(name)
        assert isinstance(entry, ExplorerEntry) and entry.name == name


@pytest.mark.parametrize(("method", "explorer"), [("drive-nav", "directions"), ("direction-360", "directions"),
                                                  ("nearest-frontier", "greedy"), ("vlfm", "vlfm")])  # fmt: skip
def test_each_method_is_an_explorer_with_body_switches(method: str, explorer: str) -> None:
    settings = load_settings(method)
    assert settings.explorer.name == explorer
    agent = make_agent(settings)
    assert agent.explorer_stats() is not None and agent.explorer_stats().name == explorer  # type: ignore[union-attr]
    assert type(explorer_section(settings, explorer)) is EXPLORERS.get(explorer).config
    assert settings_from_dict(settings_to_dict(settings)) == settings  # every section round-trips through run.json


def test_a_setting_of_one_explorer_is_its_section_and_an_unknown_explorer_is_refused() -> None:
    settings = load_settings("vlfm", overrides=["explorer.vlfm.keep_margin=0.05"])
    assert explorer_section(settings, "vlfm").keep_margin == 0.05  # type: ignore[attr-defined]
    with pytest.raises(InputError, match=r"explorer\.name.*directions, greedy, vlfm"):
        load_settings("drive-nav", overrides=["explorer.name=no-such-explorer"])
    with pytest.raises(InputError, match=r"explorer\.vlfm.*keep_radius"):
        load_settings("vlfm", overrides=["explorer.vlfm.no_such_constant=1"])


def test_a_run_json_written_before_explorers_reads_in_todays_shape() -> None:
    """run.json of an older drivenav: the agent's switches and VLFM's section under ``agent``."""
    tree = settings_to_dict(load_settings("vlfm", overrides=["explorer.vlfm.keep_margin=0.05"]))
    explorer = tree.pop("explorer")
    vlfm = {k: v for k, v in explorer["vlfm"].items() if k != "min_goal_distance"}
    tree["agent"] |= {"use_reasoner": False, "value_map": True, "decision_scan": False, "vlfm": vlfm}
    tree["agent"] |= {"min_goal_distance": 1.0, "reidentify_steps": 500}
    old = settings_from_dict(tree)
    assert old == load_settings("vlfm", overrides=["explorer.vlfm.keep_margin=0.05"])


@pytest.mark.parametrize("method", ["drive-nav", "nearest-frontier", "vlfm"])
def test_each_explorer_writes_its_own_counters(method: str) -> None:
    scene = t_junction(target_on_left=True)
    agent = make_agent(load_settings(method))
    record, _ = run_episode(
        EmbeddedEnv(lambda _: scene, SIM), agent, episode_for(scene, (12.0, 2.5), math.pi / 2, "plant"), 0, 300
    )
    assert record.success == 1 and record.explorer is not None
    counters = record.explorer.counters
    expected = {
        "drive-nav": {"labels_created", "inspection_events", "decisions", "dead_end_decisions", "selected_lost"},
        "nearest-frontier": {"decisions", "goals_skipped"},
        "vlfm": {"new_choices", "acyclic_fallbacks", "goals_skipped"},
    }[method]
    assert expected <= set(counters), counters
    if method == "vlfm":  # VLFM makes no reasoner decision; the greedy baseline one, after its start scan
        assert counters["new_choices"] >= 1 and "decisions" not in counters
    if method == "nearest-frontier":
        assert counters["decisions"] == {"scan": 1}
    assert sum(record.body.steps_by_activity.values()) == record.steps


def _fake_points(*points: tuple[str, str, str]) -> list[EntryPoint]:
    found = []
    for name, value, dist in points:
        point = EntryPoint(name, value, "drivenav.explorers")
        found.append(SimpleNamespace(name=point.name, value=point.value, dist=SimpleNamespace(name=dist)))
    return found  # type: ignore[return-value]


def test_a_broken_plugin_is_one_line_and_never_breaks_the_built_ins(monkeypatch: pytest.MonkeyPatch) -> None:
    points = _fake_points(
        ("broken", "no_such_module_anywhere:EXPLORER", "broken-pkg"),
        ("wrongtype", "math:pi", "odd-pkg"),
        ("vlfm", "their_pkg:EXPLORER", "clash-pkg"),
        ("directions", "drivenav.agent.explorers.directions.config:EXPLORER", "drivenav"),
    )
    monkeypatch.setattr(plugins, "entry_points", lambda group: points)
    registry = Registry[ExplorerEntry](
        "drivenav.explorers", BUILT_IN_EXPLORERS, lambda p: isinstance(p, ExplorerEntry), "explorer entry", "x"
    )
    assert registry.names == ("directions", "greedy", "vlfm", "broken", "wrongtype")  # the clash keeps drivenav's
    assert registry.get("vlfm").explorer.startswith("drivenav.")
    with pytest.raises(InputError) as broken:
        registry.get("broken")
    line = str(broken.value)
    assert "\n" not in line and "plug-in broken" in line and "broken-pkg" in line
    assert "no_such_module_anywhere:EXPLORER" in line and "ModuleNotFoundError" in line
    with pytest.raises(InputError, match=r"plug-in wrongtype.*odd-pkg.*float, not explorer entry"):
        registry.get("wrongtype")
    assert registry.get("directions").name == "directions"


# ----------------------------------------------------------------------------------------------- no name dispatch

NAMES = sorted({*METHOD_NAMES, *REFERENCE_AGENTS, *BUILT_IN_EXPLORERS})
_QUOTED = "|".join(re.escape(name) for name in NAMES)
DISPATCH = re.compile(
    rf"""(==|!=|\bis\b|\bin\s*[\(\[\{{])\s*["']({_QUOTED})["']|["']({_QUOTED})["']\s*(==|!=|\bin\b)"""
)
"""A comparison with a method's or explorer's name (``name == "vlfm"``, ``agent in ("drive-nav", ...)``): the
if-chains explorers replace."""


def test_no_code_dispatches_on_a_method_or_explorer_name() -> None:
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if DISPATCH.search(line):
                found.append(f"{path.relative_to(SOURCE)}:{number}: {line.strip()}")
    assert found == []


def test_the_dispatch_check_finds_an_if_chain() -> None:
    assert DISPATCH.search('    if name == "vlfm":')
    assert DISPATCH.search("    elif agent in ('nearest-frontier', 'frontier'):")
    assert not DISPATCH.search('    Method("vlfm", ("II",), "VLFM")')
    assert [m.name for m in METHODS] == list(METHOD_NAMES)
