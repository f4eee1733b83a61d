"""The typed ablation report writes exactly the files it wrote as untyped JSON.

``tests/data/ablations/`` holds ``ablations.json``, ``.md`` and ``.csv`` of a small ``bench ablations`` run (four
methods, six episodes) as written before the report was typed, and ``variant.*``: the same report edited to take
the other branches (no per-step timings, no pictures, a method without intervals or a median, no commit), with its
markdown and CSV as the untyped code wrote them (the markdown since grown by the Table I section, its ordering
lines and ApexNav's decision columns).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.analysis.ablation_data import AblationReport, Paired, SplitEntry
from drivenav.analysis.ablation_report import format_markdown, write_csv
from drivenav.analysis.ablations import paired_outcomes
from drivenav.analysis.paper_tables import TABLE_I, TABLE_I_BENCHMARKS
from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord

DATA = Path(__file__).parent / "data" / "ablations"


@pytest.mark.parametrize("name", ["ablations", "variant"])
def test_the_report_round_trips_its_json_byte_for_byte(name: str) -> None:
    text = (DATA / f"{name}.json").read_text(encoding="utf-8")
    report = AblationReport.from_json(json.loads(text))
    assert json.dumps(report.to_json(), indent=2) + "\n" == text  # what run_ablations writes


@pytest.mark.parametrize("name", ["ablations", "variant"])
def test_the_markdown_and_csv_are_those_written_before(name: str, tmp_path: Path) -> None:
    report = AblationReport.from_json(json.loads((DATA / f"{name}.json").read_text(encoding="utf-8")))
    assert format_markdown(report) == (DATA / f"{name}.md").read_text(encoding="utf-8")
    write_csv(report, tmp_path / "out.csv")
    assert (tmp_path / "out.csv").read_bytes() == (DATA / f"{name}.csv").read_bytes()


def test_a_report_of_another_shape_is_one_input_error() -> None:
    data = json.loads((DATA / "ablations.json").read_text(encoding="utf-8"))
    del data["runtime"]
    with pytest.raises(InputError, match=r"ablations\.json.*'runtime'"):
        AblationReport.from_json(data)


def test_a_report_without_pictures_reads_as_none_drawn() -> None:
    data = json.loads((DATA / "variant.json").read_text(encoding="utf-8"))
    del data["pictures"]
    report = AblationReport.from_json(data)
    assert not report.pictures.episodes and "None drawn" in format_markdown(report)


def test_the_per_split_section_is_written_only_for_episodes_with_splits() -> None:
    report = AblationReport.from_json(json.loads((DATA / "ablations.json").read_text(encoding="utf-8")))
    assert not report.splits and "splits" not in report.to_json() and "Per split" not in format_markdown(report)
    seen = SplitEntry(4, 0, 0.5, 0.25, (0.15, 0.85), (0.0, 0.5))
    unseen = SplitEntry(2, 1, 0.0, 0.0, (0.0, 0.79), (0.0, 0.0))
    with_splits = replace(report, splits={"val_seen": {"drive-nav": seen}, "val_unseen": {"frontier": unseen}})
    data = json.loads(json.dumps(with_splits.to_json()))
    assert list(data)[-1] == "splits" and data["splits"]["val_seen"]["drive-nav"]["sr_ci95"] == [0.15, 0.85]
    assert AblationReport.from_json(data) == with_splits
    markdown = format_markdown(with_splits)
    assert markdown.index("## Per split") < markdown.index("## Table VI")
    assert "| method | val_seen SR | val_seen SPL | val_unseen SR | val_unseen SPL |" in markdown
    assert "| `drive-nav` | 50.0 [15.0, 85.0] | 25.0 [0.0, 50.0] | - | - |" in markdown
    assert "| `frontier` | - | - | 0.0 [0.0, 79.0] | 0.0 [0.0, 0.0] |" in markdown
    assert "Episodes per split: val_seen (4), val_unseen (2)." in markdown


def test_table_i_pairs_every_method_with_drive_nav_episode_by_episode() -> None:
    def record(method: str, episode: str, success: int, error: bool = False) -> EpisodeRecord:
        base = EpisodeRecord(episode, "s", "chair", method, 100, 0, "error" if error else "timeout", "")
        return replace(base, success=None if error else success, spl=0.4 * success, error="E: x" if error else "")

    outcomes = {"drive-nav": (1, 1, 0, 0, 1), "apexnav": (1, 0, 1, 1, 0), "vlfm": (0, 0, 0, 1, 1)}
    runs = {m: {str(i): record(m, str(i), s, error=m == "vlfm" and i == 4) for i, s in enumerate(o)}
            for m, o in outcomes.items()}  # fmt: skip
    paired = paired_outcomes(runs)
    assert paired == {
        "apexnav": Paired("drive-nav", 5, wins=2, losses=2),  # wins: episodes 2, 3; losses: 1, 4
        "vlfm": Paired("drive-nav", 4, wins=1, losses=2),  # episode 4 ended in an error: left out
    }
    report = replace(
        AblationReport.from_json(json.loads((DATA / "ablations.json").read_text(encoding="utf-8"))), paired=paired
    )
    data = json.loads(json.dumps(report.to_json()))
    assert data["paired"]["vlfm"] == {"reference": "drive-nav", "shared": 4, "wins": 1, "losses": 2}
    assert AblationReport.from_json(data) == report
    markdown = format_markdown(report)
    assert markdown.index("## Table I: all methods") < markdown.index("## Table VI")
    assert "| `drive-nav` | 83.3 [43.6, 97.0] | 55.0 [28.4, 78.6] | 0 | 149.3 | 0.667 | reference | 50.2 / 32.6 |" in (
        markdown
    )
    assert paired_outcomes({"apexnav": runs["apexnav"]}) == {}


def test_table_i_holds_apexnavs_published_numbers() -> None:
    apexnav = next(row for row in TABLE_I if row.method == "apexnav")
    assert dict(zip(TABLE_I_BENCHMARKS, apexnav.results, strict=True)) == {
        "HM3D-OVON": None,
        "HM3Dv1": (59.6, 33.0),
        "HM3Dv2": (76.2, 38.0),
        "MP3D": (39.2, 17.8),
    }


def test_each_explorer_shows_only_its_own_kinds_of_decision() -> None:
    """Counters are written sparsely: DRIVE-Nav's triggers and ApexNav's modes share the name ``decisions``, so a
    row shows ``-`` for the other family's kinds, and 0.00 for a kind of its own that never happened."""
    report = AblationReport.from_json(json.loads((DATA / "ablations.json").read_text(encoding="utf-8")))
    base = report.methods["drive-nav"]
    apexnav = replace(base, decisions={"decisions": 5.0, "decisions.semantic": 3.0, "decisions.geometric": 2.0})
    drive_nav = replace(base, decisions={"decisions": 2.0, "decisions.scan": 1.0, "decisions.inspection": 1.0})
    markdown = format_markdown(replace(report, methods={"drive-nav": drive_nav, "apexnav": apexnav}))
    lines = markdown.split("## Decisions and direction labels per episode")[1].split("\n## ")[0].splitlines()
    header = next(line for line in lines if line.startswith("| method |")).strip("| ").split(" | ")
    cells = {row[0]: dict(zip(header, row, strict=False)) for row in (line.strip("| ").split(" | ") for line in lines)}
    kinds = ("scan", "inspection", "vanished", "stuck", "semantic", "geometric")
    assert [cells["`apexnav`"][kind] for kind in kinds] == ["-", "-", "-", "-", "3.00", "2.00"]
    assert [cells["`drive-nav`"][kind] for kind in kinds] == ["1.00", "1.00", "0.00", "0.00", "-", "-"]
