"""Explorers on one agent body: each method's explorer and settings section, the counters each explorer writes into
its records, and no dispatch on the name of a method, an explorer, a world or a robot part in the code (the registries
and their plug-ins: ``tests/test_plugins.py``)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from agent_scenes import episode_for, t_junction
from conftest import plug_in
from drivenav.agent.explorers import BUILT_IN_EXPLORERS, EXPLORERS
from drivenav.agents import make_agent
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.errors import InputError
from drivenav.eval.runner import run_episode
from drivenav.methods import METHOD_NAMES, METHODS, REFERENCE_AGENTS
from drivenav.robot.registry import BUILT_IN_MOTIONS, BUILT_IN_SOURCES
from drivenav.settings import explorer_section, load_settings, settings_from_dict, settings_to_dict
from drivenav.types import SimConfig
from drivenav.worlds import BUILT_IN_WORLDS

ROOT = Path(__file__).parents[1]
SOURCE = ROOT / "src" / "drivenav"
SIM = SimConfig()


@pytest.mark.parametrize(("method", "explorer"), [("drive-nav", "directions"), ("direction-360", "directions"),
                                                  ("nearest-frontier", "greedy"), ("vlfm", "vlfm"),
                                                  ("apexnav", "apexnav")])  # fmt: skip
def test_each_method_is_an_explorer_with_body_switches(method: str, explorer: str) -> None:
    settings = load_settings(method)
    assert settings.explorer.name == explorer
    agent = make_agent(settings)
    assert agent.explorer_counters() is not None and agent.explorer_counters().name == explorer  # type: ignore[union-attr]
    assert type(explorer_section(settings, explorer)) is EXPLORERS.get(explorer).config
    assert settings_from_dict(settings_to_dict(settings)) == settings  # every section round-trips through run.json


def test_a_setting_of_one_explorer_is_its_section_and_an_unknown_explorer_is_refused() -> None:
    settings = load_settings("vlfm", overrides=["explorer.vlfm.keep_margin=0.05"])
    assert explorer_section(settings, "vlfm").keep_margin == 0.05  # type: ignore[attr-defined]
    with pytest.raises(InputError, match=r"explorer\.name.*directions, greedy, vlfm, apexnav"):
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


@pytest.mark.parametrize("method", ["drive-nav", "nearest-frontier", "vlfm", "apexnav"])
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
        "apexnav": {"decisions", "tsp_solves", "dormant_frontiers", "settled", "goals_skipped"},
    }[method]
    assert expected <= set(counters), counters
    if method == "vlfm":  # VLFM makes no reasoner decision; the greedy baseline one, after its start scan
        assert counters["new_choices"] >= 1 and "decisions" not in counters
    if method == "nearest-frontier":
        assert counters["decisions"] == {"scan": 1}
    assert sum(record.body.steps_by_activity.values()) == record.steps


def test_a_plugin_explorer_is_a_method_with_its_own_section_and_counters(monkeypatch: pytest.MonkeyPatch) -> None:
    """The example plug-in package's farthest-frontier explorer (examples/drivenav-example), declared by its entry
    point: an ``--agent`` name, its settings section ``explorer.farthest``, its counters in the record."""
    plug_in(monkeypatch, ("drivenav.explorers", "farthest", "drivenav_example.config:EXPLORER", "drivenav-example"))
    settings = load_settings("farthest", overrides=["explorer.farthest.max_travel_time=30"])
    assert settings.explorer.name == "farthest" and not settings.agent.enrich
    assert explorer_section(settings, "farthest").max_travel_time == 30.0  # type: ignore[attr-defined]
    scene = t_junction(target_on_left=True)
    record, _ = run_episode(
        EmbeddedEnv(lambda _: scene, SIM),
        make_agent(settings),
        episode_for(scene, (12.0, 2.5), math.pi / 2, "plant"),
        0,
        300,
    )
    assert record.success == 1 and record.explorer is not None and record.explorer.name == "farthest"
    assert record.explorer.counters["goals_chosen"] >= 1 and "goals_skipped" in record.explorer.counters
    assert record.body.steps_by_activity["start_scan"] == 12


# ----------------------------------------------------------------------------------------------- no name dispatch

NAMES = sorted(
    {*METHOD_NAMES, *REFERENCE_AGENTS, *BUILT_IN_EXPLORERS, *BUILT_IN_WORLDS, *BUILT_IN_SOURCES, *BUILT_IN_MOTIONS}
)
_QUOTED = "|".join(re.escape(name) for name in NAMES)
DISPATCH = re.compile(
    rf"""(==|!=|\bis\b|\bin\s*[\(\[\{{])\s*["']({_QUOTED})["']|["']({_QUOTED})["']\s*(==|!=|\bin\b)"""
)
"""A comparison with the name of a method, an explorer, a world or a robot part (``name == "vlfm"``, ``agent in
("drive-nav", ...)``, ``source == "bag"``): the if-chains that explorers and the registries replace. (The model
backends' names are not checked yet: the served grounder ``remote`` and ``drivenav doctor``'s per-model checks name
theirs.)"""


def test_no_code_dispatches_on_the_name_of_a_registered_part() -> None:
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if DISPATCH.search(line):
                found.append(f"{path.relative_to(SOURCE)}:{number}: {line.strip()}")
    assert found == []


def test_the_dispatch_check_finds_an_if_chain() -> None:
    assert DISPATCH.search('    if name == "vlfm":')
    assert DISPATCH.search("    elif agent in ('nearest-frontier', 'frontier'):")
    assert DISPATCH.search('    if source == "bag":') and DISPATCH.search('    if args.env != "habitat":')
    assert not DISPATCH.search('    Method("vlfm", ("II",), "VLFM")')
    assert [m.name for m in METHODS] == list(METHOD_NAMES)
