"""Hostile settings (issue 60): ApexNav's prompt templates are formatted once at load and bounded, its TSP's
solution count is bounded in time, and ``config show`` refuses what a run refuses -- a broken plug-in explorer or
model, a grounder timeout past an hour, a ``--config`` file of another method than ``--agent`` -- while
``ablations.json`` stays JSON whatever the counters hold."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conftest import plug_in
from drivenav.agent.base import ExplorerCounters
from drivenav.analysis.ablation_data import AblationReport
from drivenav.analysis.ablation_report import format_markdown
from drivenav.analysis.ablations import method_entry
from drivenav.cli import main
from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord
from drivenav.settings import load_settings, settings_to_yaml

PLUGINS = """
from drivenav.agent.config import ExplorerEntry
from drivenav.agent.explorers.greedy.config import GreedyConfig

BROKEN_CLASS = ExplorerEntry("broken-class", GreedyConfig, "hostile60_missing:Explorer", "no class", ())
"""

BROKEN_MODEL = "raise RuntimeError('this grounder cannot load')\n"


def _one_line_exit_2(capsys: pytest.CaptureFixture[str], args: list[str], *words: str) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


@pytest.fixture
def broken(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """An explorer whose class cannot be imported and a grounder whose module raises, both installed."""
    (tmp_path / "hostile60_plugins.py").write_text(PLUGINS, encoding="utf-8")
    (tmp_path / "hostile60_grounder.py").write_text(BROKEN_MODEL, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    plug_in(
        monkeypatch,
        ("drivenav.explorers", "broken-class", "hostile60_plugins:BROKEN_CLASS", "hostile60"),
        ("drivenav.grounders", "broken-grounder", "hostile60_grounder:GROUNDER", "hostile60"),
    )


# ----------------------------------------------------------------------------------------- ApexNav's prompt


@pytest.mark.parametrize(
    ("template", "words"),
    [
        ("a {target} {nope}", "{nope}"),
        ("a {target} {", "unmatched braces"),
        ("a {target}{0}", "{0}"),
        ("a {target}{}", "{}"),
        ("a {target.upper}", "{target.upper}"),
        ("a {{target}}", "no {target} field"),
        ("a {room}", "no {target} field"),
        ("{room!r:>99999999} {target}", "{room!r:>99999999}"),
        ("{target}" * 200, "1600 characters"),
        ("{target}" * 100, "a text of 10000 characters"),
    ],
)
@pytest.mark.parametrize("key", ["prompt", "prompt_anywhere"])
def test_a_prompt_template_that_would_fail_or_blow_up_is_refused_at_load(key: str, template: str, words: str) -> None:
    with pytest.raises(InputError, match=f"explorer.apexnav.{key}") as refused:
        load_settings("apexnav", overrides=[f"explorer.apexnav.{key}={json.dumps(template)}"])
    assert words in str(refused.value) and "\n" not in str(refused.value)


@pytest.mark.parametrize("template", ["Seems like a {target} ahead?", "{room}, {target}, {{literal}}", "{target}"])
def test_a_plain_prompt_template_loads(template: str) -> None:
    settings = load_settings("apexnav", overrides=[f"explorer.apexnav.prompt={json.dumps(template)}"])
    assert settings.explorer.apexnav.prompt == template  # type: ignore[attr-defined]


def test_the_tsp_solution_count_is_bounded_in_time() -> None:
    with pytest.raises(InputError, match=r"tsp_solutions.*\[1, 500\]"):
        load_settings("apexnav", overrides=["explorer.apexnav.tsp_solutions=100000"])
    assert load_settings("apexnav", overrides=["explorer.apexnav.tsp_solutions=500"])


# ----------------------------------------------------------------------------------------- config show


def test_a_grounder_timeout_past_an_hour_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    _one_line_exit_2(capsys, ["config", "show", "--set", "models.detector_timeout_s=7200"], "detector_timeout_s")
    assert load_settings(overrides=["models.detector_timeout_s=3600"]).models.detector_timeout_s == 3600


@pytest.mark.usefixtures("broken")
@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("explorer.name=broken-class", "hostile60_missing"),
        ("models.detector=broken-grounder", "this grounder cannot load"),
    ],
)
def test_config_show_refuses_a_broken_plugin_as_a_run_does(
    setting: str, words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _one_line_exit_2(capsys, ["config", "show", "--set", setting], words)


@pytest.mark.parametrize("shown", ["apexnav", "vlfm", None])
def test_a_config_file_of_another_method_than_agent_is_one_line(
    shown: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    saved = tmp_path / "shown.yaml"
    saved.write_text(settings_to_yaml(load_settings(shown)), encoding="utf-8")
    agent = "drive-nav" if shown else "vlfm"
    err = _one_line_exit_2(capsys, ["config", "show", "--agent", agent, "--config", str(saved)], str(saved))
    assert "run.agent" in err or "explorer.name" in err


def test_a_config_file_of_the_same_method_or_of_constants_only_still_loads(tmp_path: Path) -> None:
    saved = tmp_path / "shown.yaml"
    settings = load_settings("apexnav", overrides=["explorer.apexnav.tsp_solutions=60"])
    saved.write_text(settings_to_yaml(settings), encoding="utf-8")
    assert load_settings("apexnav", configs=[str(saved)]) == settings
    constants = tmp_path / "constants.yaml"
    constants.write_text("sim:\n  max_steps: 77\nexplorer:\n  directions:\n    decision_scan: false\n")
    assert load_settings("drive-nav", configs=[str(constants), "quick"]).sim.max_steps > 0


# ----------------------------------------------------------------------------------------- ablations.json


def test_counters_whose_sum_overflows_keep_ablations_json_json() -> None:
    records = [
        EpisodeRecord(
            str(k), "s", "chair", "drive-nav", 10, 0, "timeout", "", success=False, spl=0.0,
            explorer=ExplorerCounters("my-explorer", {"huge": 1e308, "fine": 2}),
        )
        for k in range(2)
    ]  # fmt: skip
    entry = method_entry(records)
    assert entry.decisions["huge"] is None and entry.decisions["fine"] == 2.0
    text = json.dumps(entry.to_json(), allow_nan=False)  # no Infinity: JSON
    assert '"huge": null' in text


def test_an_overflowed_mean_reads_back_and_is_shown_as_such(tmp_path: Path) -> None:
    stored = Path(__file__).parent / "data" / "ablations"
    source = next(stored.glob("*.json"))
    data = json.loads(source.read_text(encoding="utf-8"))
    method = next(iter(data["methods"]))
    data["methods"][method]["decisions"]["huge"] = None
    report = AblationReport.from_json(data, source)
    assert report.methods[method].decisions["huge"] is None
    assert "overflow" in format_markdown(report)


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("agent:\n  stop_distance: -1\n", "agent.stop_distance"),
        ("explorer:\n  directions:\n    settle_steps: -3\n", "explorer.directions.settle_steps"),
    ],
)
def test_a_range_error_from_a_config_file_names_the_file(text: str, key: str, tmp_path: Path) -> None:
    """The line names the file that gave the value, not the merged 'settings' (and --set for a --set)."""
    config = tmp_path / "bad.yaml"
    config.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as raised:
        load_settings("drive-nav", configs=[str(config)])
    assert raised.value.source == str(config) and raised.value.field == key
    with pytest.raises(InputError) as raised:
        load_settings("drive-nav", configs=[str(config)], overrides=[f"{key}=-5"])
    assert raised.value.source == "--set" and raised.value.field == key
