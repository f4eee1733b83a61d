"""Issue 60: the reasoner's calls and the image-text scorer's in columns of their own wherever model calls are
counted (summary.json, eval's table, ablations.json and its markdown, ``compare``, the report's pages), never added
into one "VLM calls"; and ``episodes stats`` with a progress line on a terminal's stderr."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import pytest

from drivenav.agent.base import CallSplit, ModelCounters, split_calls
from drivenav.analysis.ablation_data import AblationReport, MethodEntry
from drivenav.analysis.ablation_report import format_markdown
from drivenav.analysis.ablations import method_entry
from drivenav.analysis.compare import compare_runs, format_comparison
from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.report import Summary, format_table, summarize
from drivenav.report.episode_page import _facts
from drivenav.report.episodes_page import COLUMNS, EpisodeRow
from drivenav.report.index_page import _run_row, _runs_table
from drivenav.report.runs import Run
from drivenav.types import SimConfig

DATA = Path(__file__).parent / "data" / "ablations"
PLUS = {"category_hints": 1, "select_direction": 6, "score": 30}  # drive-nav-plus: 7 questions, 30 views scored


def _record(
    episode: int, by_kind: dict[str, int], total: int | None = None, agent: str = "drive-nav-plus"
) -> EpisodeRecord:
    calls = sum(by_kind.values()) if total is None else total
    stats = ModelCounters(by_kind)
    return EpisodeRecord(str(episode), "s", "chair", agent, 10, 0, "timeout", "", vlm_calls=calls, stats=stats)


def _run(records: list[EpisodeRecord]) -> Run:
    return Run("plus", Path("runs/plus"), None, tuple(records), {}, {}, method_entry(records))


def test_each_call_kind_belongs_to_one_model_and_an_old_record_cannot_tell() -> None:
    assert split_calls(PLUS, 37) == CallSplit(reasoner=7, scorer=30)
    assert split_calls({"verify": 2, "propose_prompt": 1, "judge_floor": 1}, 4) == CallSplit(4, 0)
    assert split_calls({}, 0) == CallSplit(0, 0)  # a model-free agent
    assert split_calls({}, 12) is None  # a record written without vlm_calls_by_kind: unknown, not zero
    assert split_calls({"caption": 3}, 3) is None  # a kind of no known model


def test_summary_json_keeps_its_keys_and_adds_the_split() -> None:
    summary = summarize([_record(0, PLUS), _record(1, {"select_direction": 3, "score": 10})])
    data = summary.to_json()
    assert (data["avg_vlm_calls"], data["median_vlm_calls"]) == (25.0, 25.0)  # as before: both models added
    assert (data["avg_reasoner_calls"], data["median_reasoner_calls"]) == (5.0, 5.0)
    assert (data["avg_scorer_calls"], data["median_scorer_calls"]) == (20.0, 20.0)
    assert Summary.from_json(json.loads(json.dumps(data))) == summary
    table = format_table(summary)
    assert "avg reasoner calls      5.00" in table and "avg scorer calls        20.00" in table
    assert "VLM calls" not in table


def test_records_without_calls_by_kind_give_an_unknown_split() -> None:
    data = summarize([_record(0, {}, total=40)]).to_json()
    assert data["avg_vlm_calls"] == 40.0
    assert [data[k] for k in ("avg_reasoner_calls", "median_reasoner_calls", "avg_scorer_calls")] == [None] * 3
    assert "avg reasoner calls      n/a" in format_table(Summary.from_json(data))


def test_a_summary_written_before_the_split_reads_and_writes_its_own_keys() -> None:
    old = {
        k: v for k, v in summarize([_record(0, PLUS)]).to_json().items() if "reasoner" not in k and "scorer" not in k
    }
    assert Summary.from_json(old).to_json() == old


def test_ablations_json_and_its_markdown_split_the_calls() -> None:
    entry = method_entry([_record(0, PLUS), _record(1, PLUS)])
    data = entry.to_json()
    assert (data["vlm_calls"], data["median_vlm_calls"]) == (37.0, 37)
    assert (data["avg_reasoner_calls"], data["avg_scorer_calls"]) == (7.0, 30.0)
    assert MethodEntry.from_json(data) == entry
    stored = AblationReport.from_json(json.loads((DATA / "ablations.json").read_text(encoding="utf-8")))
    markdown = format_markdown(AblationReport(**{**stored.__dict__, "methods": {"drive-nav-plus": entry}}))
    assert "| method | reasoner calls (median / mean) | scorer calls (median / mean) |" in markdown
    assert "| `drive-nav-plus` | 7 / 7.0 | 30 / 30.0 |" in markdown


def test_compare_prints_reasoner_and_scorer_calls_apart() -> None:
    runs = {"drive-nav-plus": {"0": _record(0, PLUS)}, "old": {"0": _record(0, {}, total=12, agent="drive-nav")}}
    comparison = compare_runs(runs)
    table = format_comparison(comparison)
    header, _, plus, old = table.splitlines()
    assert "reasoner calls scorer calls" in header
    assert plus.split("|")[0].split()[-2:] == ["7.00", "30.00"]
    assert old.split("|")[0].split()[-2:] == ["n/a", "n/a"]
    overall = comparison.to_json()["methods"]["drive-nav-plus"]["overall"]
    assert (overall["avg_reasoner_calls"], overall["avg_scorer_calls"]) == (7.0, 30.0)


def test_the_report_pages_show_reasoner_and_scorer_calls_in_columns_of_their_own() -> None:
    run = _run([_record(0, PLUS), _record(1, {}, total=9)])
    assert "VLM calls" not in _runs_table([run]) and "reasoner calls" in _runs_table([run])
    assert [str(c) for c in _run_row(run)][7:9] == ["7.00", "30.00"]  # over the record that tells them apart
    assert COLUMNS[-2:] == ("reasoner calls", "scorer calls") and "VLM calls" not in COLUMNS
    cells = [EpisodeRow(run, record).cells()[-2:] for record in run.records]
    assert [[c.html for c in row] for row in cells] == [["7", "30"], ["n/a", "n/a"]]  # type: ignore[union-attr]
    facts = _facts(run.records[0], None)
    assert "reasoner calls</dt><dd>7 (category_hints 1, select_direction 6)" in facts
    assert "scorer calls</dt><dd>30<" in facts and "VLM calls" not in facts
    assert "reasoner calls</dt><dd>n/a" in _facts(run.records[1], None)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def episodes_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("stats") / "few.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural:1", 0), 3, 0, SimConfig(), Storeys(None)), path)
    return path


def test_episodes_stats_draws_progress_on_a_terminals_stderr_only(
    episodes_file: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["episodes", "stats", str(episodes_file), "--json"]) == 0
    drawn = terminal.getvalue()
    assert all(f"episodes stats: {stage}" in drawn for stage in ("reading", "checking", "measuring"))
    assert "/3 " in drawn  # of the 3 episodes
    out = capsys.readouterr().out
    assert "episodes stats" not in out and json.loads(out)  # stdout holds the JSON alone
    monkeypatch.undo()
    assert main(["episodes", "stats", str(episodes_file), "--json"]) == 0
    assert "episodes stats" not in capsys.readouterr().err  # not a terminal: no bar in a log
