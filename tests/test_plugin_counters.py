"""A plug-in explorer's counters and trace events (issue 59): declared by its entry, shown by the report's decisions
table and episode page, drawn by ``drivenav viz``; and what the body refuses of an explorer (counters out of the
record's range, an action that is no Action, an event that cannot be saved): that episode ends in an ``error``
record naming the explorer, and the run directory stays readable."""

from __future__ import annotations

import importlib
import json
import math
from pathlib import Path
from types import ModuleType

import pytest

from conftest import plug_in
from drivenav.agent.trace import OpaqueEvent, event_from_dict
from drivenav.cli import main
from drivenav.eval.records import read_records

PLUGIN = """
from dataclasses import dataclass, field
from typing import ClassVar

from drivenav.agent.config import CounterSpec, EventSpec, ExplorerEntry
from drivenav.agent.explorers.greedy.config import GreedyConfig
from drivenav.agent.explorers.greedy.explorer import GreedyExplorer
from drivenav.agent.trace import Event

BAD_COUNTERS = None  # what counters() returns instead of its own, when set by a test
BAD_ACTION = None  # likewise act()
BAD_EVENT = None  # an event added at every act, when set


@dataclass(frozen=True)
class Pocket(Event):
    depth: float
    kind: ClassVar[str] = "pocket"


@dataclass
class PocketCounters:
    pockets: int = 0
    reach: float = 0.0
    sides: dict = field(default_factory=dict)


class PocketExplorer(GreedyExplorer):
    def __init__(self, setup):
        super().__init__(setup)
        self.pockets = 0

    def act(self, loop, observation, ctx):
        action = super().act(loop, observation, ctx)
        if loop.step % 10 == 0:
            self.pockets += 1
            loop.trace.add(Pocket(loop.step, 1.5))
        if BAD_EVENT is not None:
            loop.trace.add(BAD_EVENT)
        return BAD_ACTION if BAD_ACTION is not None else action

    def counters(self):
        if BAD_COUNTERS is not None:
            return BAD_COUNTERS
        return PocketCounters(self.pockets, 2.5, {"left": self.pockets})


EXPLORER = ExplorerEntry(
    "pocket",
    GreedyConfig,
    "pocketpkg:PocketExplorer",
    "greedy, counting pockets",
    ("agent.enrich=false", "agent.verify=false"),
    counters=(CounterSpec("pockets", "pockets found"), CounterSpec("sides", kind="by_kind", kinds=("left",))),
    events=(EventSpec("pocket", ("depth",), marker="triangle", color=(200, 0, 100), label="pocket seen"),),
)


@dataclass
class Bad:
    value: object
"""


@pytest.fixture
def pocket(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """The plug-in package ``pocketpkg`` (explorer ``pocket``), importable and installed for the test."""
    folder = tmp_path_factory.getbasetemp() / "pocket-plugin"
    folder.mkdir(exist_ok=True)
    (folder / "pocketpkg.py").write_text(PLUGIN, encoding="utf-8")
    monkeypatch.syspath_prepend(str(folder))
    plug_in(monkeypatch, ("drivenav.explorers", "pocket", "pocketpkg:EXPLORER", "pocketpkg"))
    module = importlib.import_module("pocketpkg")
    for name in ("BAD_COUNTERS", "BAD_ACTION", "BAD_EVENT"):
        monkeypatch.setattr(module, name, None)
    return module


def _eval(out: Path, agent: str = "pocket", episodes: int = 2) -> None:
    args = ["eval", "--agent", agent, "--scenes", "procedural:1", "--episodes", str(episodes)]
    assert main([*args, "--max-steps", "40", "--out", str(out)]) == 0


def test_the_report_shows_a_plugin_explorers_counters_and_events(pocket: ModuleType, tmp_path: Path) -> None:
    _eval(tmp_path / "pocket")
    _eval(tmp_path / "nearest-frontier", "nearest-frontier")
    records = read_records(tmp_path / "pocket" / "episodes.jsonl")
    assert all(r.explorer is not None and r.explorer.counters["pockets"] >= 1 for r in records)
    site = tmp_path / "site"
    assert main(["report", str(tmp_path / "pocket"), str(tmp_path / "nearest-frontier"), "--out", str(site)]) == 0
    index = (site / "index.html").read_text(encoding="utf-8")
    assert ">pockets found<" in index and ">left<" in index and ">reach<" in index  # declared, and by its key
    pages = list((site / "runs" / "pocket" / "episodes").glob("*.html"))
    page = pages[0].read_text(encoding="utf-8")
    assert "Explorer events" in page and "pocket seen" in page and "depth: 1.5" in page
    assert "Counters of the pocket explorer" in page and "pockets found" in page
    assert "cannot be read" not in page


def test_viz_draws_a_trace_with_an_event_of_no_known_kind(tmp_path: Path) -> None:
    """A trace holding a plug-in's event, read where the plug-in is not installed: kept opaque, drawn as a marker."""
    _eval(tmp_path / "run", "nearest-frontier", 1)
    trace_file = next((tmp_path / "run" / "traces").glob("*.json"))
    data = json.loads(trace_file.read_text(encoding="utf-8"))
    data["events"].append({"kind": "whirl", "step": 3, "spin": [1, {"a": None}]})
    trace_file.write_text(json.dumps(data), encoding="utf-8")
    event = event_from_dict(data["events"][-1])
    assert isinstance(event, OpaqueEvent) and event.to_dict() == data["events"][-1]
    assert main(["viz", str(tmp_path / "run"), data["episode_id"], "--out", str(tmp_path / "viz")]) == 0
    assert list((tmp_path / "viz").rglob("*.png"))


def _assert_error_episode(run: Path, words: str, bad_counters: bool = True) -> None:
    """Every episode of ``run`` is an error naming the explorer and ``words`` (its counters left out where they were
    what was wrong); the run reads, reruns and reports."""
    records = read_records(run / "episodes.jsonl")
    assert records and all(r.is_error for r in records)
    assert all("pocket" in r.error and words in r.error for r in records), records[0].error
    assert all(r.explorer is not None and (r.explorer.counters == {}) == bad_counters for r in records)
    _eval(run, episodes=1)  # a rerun reads the run's own file
    assert main(["report", str(run), "--out", str(run.parent / "site"), "--pictures", "none"]) == 0


@pytest.mark.parametrize(
    ("value", "words"),
    [
        (math.nan, "nan"),
        (math.inf, "inf"),
        (-1, "-1"),
        ("many", "'many'"),
        ([1, 2], "[1, 2]"),
        (10**5000, "an integer of"),
        ({"left": -2}, "{'left': -2}"),
        (True, "True"),
    ],
    ids=["nan", "inf", "negative", "str", "list", "5000-digit", "negative-kind", "bool"],
)
def test_counters_out_of_the_record_range_end_the_episode_in_an_error(
    pocket: ModuleType, tmp_path: Path, value: object, words: str
) -> None:
    pocket.BAD_COUNTERS = pocket.Bad(value)
    _eval(tmp_path / "run", episodes=1)
    _assert_error_episode(tmp_path / "run", words)


def test_counters_that_are_no_dataclass_end_the_episode_in_an_error(pocket: ModuleType, tmp_path: Path) -> None:
    pocket.BAD_COUNTERS = {"pockets": 1}
    _eval(tmp_path / "run", episodes=1)
    _assert_error_episode(tmp_path / "run", "not a dataclass")


def test_an_unknown_action_ends_the_episode_in_an_error(pocket: ModuleType, tmp_path: Path) -> None:
    pocket.BAD_ACTION = 7
    _eval(tmp_path / "run", episodes=1)
    _assert_error_episode(tmp_path / "run", "not an Action member", bad_counters=False)


def test_an_event_that_cannot_be_saved_ends_the_episode_in_an_error(pocket: ModuleType, tmp_path: Path) -> None:
    pocket.BAD_EVENT = pocket.Pocket(1, math.nan)
    _eval(tmp_path / "run", episodes=1)
    _assert_error_episode(tmp_path / "run", "depth is nan", bad_counters=False)
    trace = next((tmp_path / "run" / "traces").glob("*.json")).read_text(encoding="utf-8")
    assert "NaN" not in trace
