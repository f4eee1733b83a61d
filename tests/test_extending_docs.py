"""docs/extending.md's complete example explorer runs as written: its files (the code blocks titled with a path) are
written as a throwaway package, its entry points (from the example's own pyproject.toml) declared, and two short
episodes run through ``drivenav eval`` with its explorer and with its variant row."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import tomllib

from conftest import REPO, plug_in
from drivenav.cli import main
from drivenav.eval import runner

DOCS = REPO / "docs" / "extending.md"
BLOCK = re.compile(r'^```(?:python|toml) title="([^"]+)"\n(.*?)^```$', re.MULTILINE | re.DOTALL)
"""A code block of the example: its file's path (relative to the package folder) and its text."""


def example_files() -> dict[str, str]:
    """The example package's files as the docs give them, by path."""
    return {path: text for path, text in BLOCK.findall(DOCS.read_text(encoding="utf-8"))}


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The docs' package written to a folder once (imported once: its event class registers its kind once)."""
    root = tmp_path_factory.mktemp("largest")
    for path, text in example_files().items():
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text(text, encoding="utf-8")
    return root


@pytest.fixture
def largest(package: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The docs' package on the path and its entry points declared, as its pyproject.toml gives them."""
    monkeypatch.syspath_prepend(str(package))
    project = tomllib.loads((package / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    points = [
        (group, name, value, project["name"])
        for group, entries in project["entry-points"].items()
        for name, value in entries.items()
    ]
    plug_in(monkeypatch, *points)
    monkeypatch.setattr(runner, "_WORKER", None)


def test_the_docs_give_a_complete_package() -> None:
    files = example_files()
    assert set(files) == {
        "pyproject.toml",
        "drivenav_largest/__init__.py",
        "drivenav_largest/config.py",
        "drivenav_largest/explorer.py",
        "drivenav_largest/methods.py",
    }
    assert "Loop" not in files["drivenav_largest/explorer.py"]  # written against the step's handles, by name


@pytest.mark.parametrize("agent", ["largest", "largest-near"])
@pytest.mark.usefixtures("largest")
def test_the_docs_example_runs_two_episodes(agent: str, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["eval", "--agent", agent, "--scenes", "procedural:1", "--episodes", "2", "--max-steps", "40"]
    assert main([*args, "--out", str(out)]) == 0
    records = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert len(records) == 2 and not any(record["error"] for record in records)
    assert all(record["explorer"]["name"] == "largest" for record in records)
    assert all(set(record["explorer"]["counters"]) == {"goals_chosen", "goals_skipped"} for record in records)
    assert all(record["steps_by_activity"]["start_scan"] == 12 for record in records)
    config = json.loads((out / "run.json").read_text())["config"]
    reach = 6.0 if agent == "largest-near" else 15.0
    assert config["explorer"]["largest"]["max_travel_time"] == reach
    goals = [
        event
        for trace in sorted((out / "traces").glob("*.json"))
        for event in json.loads(trace.read_text())["events"]
        if event["kind"] == "largest_goal"
    ]
    chosen = sum(record["explorer"]["counters"]["goals_chosen"] for record in records)
    assert chosen >= 1 and len(goals) == chosen  # the explorer's own event, one per goal chosen


@pytest.mark.usefixtures("largest")
def test_the_docs_example_is_shown_as_it_declares_and_its_ranges_are_checked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "largest"
    args = ["eval", "--agent", "largest", "--scenes", "procedural:1", "--episodes", "1", "--max-steps", "40"]
    assert main([*args, "--out", str(out)]) == 0
    assert main(["report", str(out), "--out", str(tmp_path / "site")]) == 0
    page = next((tmp_path / "site" / "runs" / "largest" / "episodes").glob("*.html")).read_text(encoding="utf-8")
    assert "Counters of the largest explorer" in page and "skipped" in page  # its counters, by their declared titles
    assert "Explorer events" in page and "frontier_id" in page  # its own event, with the declared fields
    capsys.readouterr()
    assert main(["config", "show", "--agent", "largest", "--set", "explorer.largest.max_travel_time=-5"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "explorer.largest.max_travel_time" in error, error
