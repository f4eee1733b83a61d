"""Methods (table rows, ablation variants) from entry points: a plug-in package brings its rows (group
``drivenav.methods``, an entry naming a :class:`~drivenav.methods.Method` or a tuple of them; the example package's
``farthest`` and ``farthest-near``). ``--agent``, ``bench ablations --methods`` and the listing of methods see them;
a name a built-in has is ignored with one warning; a broken entry is refused alone, in one line, when chosen."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest

from conftest import plug_in
from drivenav.analysis.ablations import parse_methods
from drivenav.cli import main
from drivenav.errors import InputError
from drivenav.eval import runner
from drivenav.methods import ALL_METHODS, METHOD_NAMES, agent_names, method_named
from drivenav.settings import explorer_section, load_settings

EXAMPLE = [
    ("drivenav.explorers", "farthest", "drivenav_example.config:EXPLORER", "drivenav-example"),
    ("drivenav.methods", "farthest", "drivenav_example.methods:ROWS", "drivenav-example"),
]
"""The example package's explorer and its rows, as its pyproject.toml declares them."""

CLASHING = """
from drivenav.methods import Method

ROWS = (
    Method("drive-nav", (), "not drivenav's drive-nav", ("agent.enrich=false",)),
    Method("oracle", (), "not the oracle"),
    Method("odd-one", (), "DRIVE-Nav with another merge tolerance", ("paper.directions.merge_tolerance=1.0",)),
)
ONE = Method("lone", (), "one method, not a tuple", ("agent.verify=false",))
"""


@pytest.fixture
def clashing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A throwaway plug-in module of methods on the path: rows of which two take built-in names, and one method."""
    (tmp_path / "clashing_rows.py").write_text(CLASHING)
    monkeypatch.syspath_prepend(str(tmp_path))


def test_a_plugin_package_brings_its_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    plug_in(monkeypatch, *EXAMPLE)
    assert {"farthest", "farthest-near"} <= set(agent_names())
    near = method_named("farthest-near")
    assert near is not None and near.base == "farthest" and near.explorer == "farthest"
    settings = load_settings("farthest-near")
    assert settings.explorer.name == "farthest" and not settings.agent.enrich  # the explorer entry's body switches
    assert explorer_section(settings, "farthest").max_travel_time == 6.0  # type: ignore[attr-defined]
    row = method_named("farthest")  # the package's own row of its explorer, not the method made of the explorer
    assert row is not None and row.description.startswith("the farthest frontier point")
    assert parse_methods("drive-nav,farthest-near") == ["drive-nav", "farthest-near"]


def test_the_built_in_methods_keep_their_names_and_order(monkeypatch: pytest.MonkeyPatch) -> None:
    before = agent_names()
    plug_in(monkeypatch, *EXAMPLE)
    assert [name for name in agent_names() if name in before] == before
    assert METHOD_NAMES[: len(ALL_METHODS)] == ALL_METHODS and "farthest" not in METHOD_NAMES


def test_a_name_taken_by_a_built_in_is_ignored_with_one_warning(
    monkeypatch: pytest.MonkeyPatch, clashing: None, caplog: pytest.LogCaptureFixture
) -> None:
    plug_in(
        monkeypatch,
        ("drivenav.methods", "clashing", "clashing_rows:ROWS", "clashing-pkg"),
        ("drivenav.methods", "lone", "clashing_rows:ONE", "clashing-pkg"),
    )
    with caplog.at_level(logging.WARNING, logger="drivenav.methods"):
        names = agent_names()
        agent_names()
        method_named("drive-nav")
    assert {"odd-one", "lone"} <= set(names) and names.count("drive-nav") == 1
    drive_nav = method_named("drive-nav")
    assert drive_nav is not None and drive_nav.overrides == () and drive_nav.tables  # drivenav's own
    assert load_settings("drive-nav").agent.enrich and load_settings("odd-one").paper.directions.merge_tolerance == 1.0
    warned = [record.getMessage() for record in caplog.records]
    assert len(warned) == 2, warned  # drive-nav and oracle, once each
    assert all("clashing-pkg" in line and "is ignored" in line for line in warned)


def test_a_broken_entry_is_refused_alone_when_chosen(monkeypatch: pytest.MonkeyPatch) -> None:
    plug_in(
        monkeypatch,
        *EXAMPLE,
        ("drivenav.methods", "gone", "no_such_module_anywhere:ROWS", "gone-pkg"),
        ("drivenav.methods", "wrong", "math:pi", "odd-pkg"),
    )
    assert {"gone", "wrong", "farthest-near"} <= set(agent_names())
    with pytest.raises(InputError) as gone:
        load_settings("gone")
    line = str(gone.value)
    assert "\n" not in line and "plug-in gone" in line and "gone-pkg" in line and "ModuleNotFoundError" in line
    with pytest.raises(InputError, match=r"plug-in wrong.*odd-pkg.*float, not method"):
        load_settings("wrong")
    assert load_settings("drive-nav").explorer.name == "directions"
    assert load_settings("farthest-near").explorer.name == "farthest"
    with pytest.raises(InputError, match="plug-in gone"):
        parse_methods("drive-nav,gone")  # bench ablations --methods: the same line, before any run


def test_a_plugin_row_runs_through_the_command_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    plug_in(monkeypatch, *EXAMPLE)
    monkeypatch.setattr(runner, "_WORKER", None)
    args = ["eval", "--agent", "farthest-near", "--scenes", "procedural:1", "--episodes", "1", "--max-steps", "20"]
    assert main([*args, "--out", str(tmp_path / "run")]) == 0
    config = json.loads((tmp_path / "run" / "run.json").read_text())["config"]
    assert config["run"]["agent"] == "farthest-near" and config["explorer"]["farthest"]["max_travel_time"] == 6.0
    record = json.loads((tmp_path / "run" / "episodes.jsonl").read_text().splitlines()[0])
    assert record["agent"] == "farthest-near" and record["explorer"]["name"] == "farthest"
