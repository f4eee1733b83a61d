"""``drivenav report``: the static site of runs and episodes, checked without a browser (the browser's tests are
``test_report_browser.py``): valid HTML, self-contained links, the numbers in the tables, the pictures policy."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import html5lib
import pytest

from drivenav.analysis.stats import wilson_interval
from drivenav.cli import main
from drivenav.eval.records import read_records
from drivenav.report.config import PictureChoice, ReportConfig
from drivenav.report.episodes_page import pivot_pairs
from drivenav.report.markdown import to_html
from drivenav.report.runs import config_differences, flatten, load_run, run_names
from drivenav.report.site import write_report
from drivenav.report.timing_plot import _binned

METHODS = ("drive-nav", "frontier")
TINY = ["--episodes", "4", "--max-steps", "30", "--scenes", "procedural:2", "--pictures", "1"]
MODELS = ["--reasoner", "geometric", "--detector", "ground-truth"]


@pytest.fixture(scope="module")
def ablations(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny ``bench ablations`` folder (two methods, four episodes, some failures) with its report."""
    out = tmp_path_factory.mktemp("ablations")
    assert main(["bench", "ablations", *TINY, *MODELS, "--methods", ",".join(METHODS), "--out", str(out)]) == 0
    return out


def pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


class _References(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.found: list[str] = []
        self.ids: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        self.found.extend(v for k, v in attrs if k in ("href", "src") and v)
        if values.get("id"):
            self.ids.append(str(values["id"]))


def references(page: Path) -> _References:
    parser = _References()
    parser.feed(page.read_text(encoding="utf-8"))
    return parser


def test_bench_ablations_writes_a_valid_self_contained_site(ablations: Path) -> None:
    site = ablations / "report"
    assert (site / "index.html").is_file()
    strict = html5lib.HTMLParser(strict=True)
    for page in pages(site):
        strict.parse(page.read_text(encoding="utf-8"))  # raises on the first parse error
        found = references(page)
        assert len(found.ids) == len(set(found.ids)), page
        for target in found.found:
            assert not re.match(r"^[a-z]+://", target), f"{page}: {target} is not in the site"
            path = target.split("#")[0]
            if path:
                assert (page.parent / path).resolve().is_file(), f"{page}: {target}"
    runs = [ablations / "runs" / method for method in METHODS]
    episodes = sum(len(read_records(run / "episodes.jsonl")) for run in runs)
    assert len(list((site / "runs").glob("*/episodes/*.html"))) == episodes


def test_the_index_shows_each_runs_rates_with_intervals_and_the_settings_that_differ(ablations: Path) -> None:
    index = (ablations / "report" / "index.html").read_text(encoding="utf-8")
    for method in METHODS:
        records = read_records(ablations / "runs" / method / "episodes.jsonl")
        successes = sum(int(r.success or 0) for r in records)
        low, high = wilson_interval(successes, len(records))
        assert f"{100 * successes / len(records):.1f} [{100 * low:.1f}, {100 * high:.1f}]" in index
    assert "<td>agent.enrich</td><td>true</td><td>false</td>" in index  # drive-nav enriches, frontier does not
    assert "Table VI: module ablation" in index and "Table II: common successful episodes" in index
    assert "Table I: all methods" in index and "reference" in index  # every method beside drive-nav
    assert "Pictures" not in re.findall(r"<h\d>([^<]*)</h\d>", index)


def test_the_episodes_table_has_a_row_per_episode_and_run_with_its_values(ablations: Path) -> None:
    table = (ablations / "report" / "episodes.html").read_text(encoding="utf-8")
    rows = re.findall(r'<tr data-method="([^"]*)" data-episode="([^"]*)" data-success="([^"]*)"', table)
    expected = {
        (method, r.episode_id, str(r.success))
        for method in METHODS
        for r in read_records(ablations / "runs" / method / "episodes.jsonl")
    }
    assert set(rows) == expected and len(rows) == len(expected)
    assert '<form id="filters" hidden' in table  # shown by the script only: the table alone reads without it


def test_failed_episodes_get_a_picture_and_reuse_the_ones_drawn(ablations: Path) -> None:
    site = ablations / "report"
    for method in METHODS:
        for record in read_records(ablations / "runs" / method / "episodes.jsonl"):
            page = (site / "runs" / method / "episodes" / f"{record.episode_id}.html").read_text(encoding="utf-8")
            drawn_by_bench = (ablations / "pictures" / method / f"{record.episode_id}_topdown.png").is_file()
            has_picture = "_topdown.png" in page
            assert has_picture == (not record.success or drawn_by_bench), (method, record.episode_id)
            assert f"../records/{record.episode_id}.json" in page and f"../traces/{record.episode_id}.json" in page
            copied = json.loads((site / "runs" / method / "records" / f"{record.episode_id}.json").read_text())
            assert copied == record.to_json()


def test_picture_flags_limit_what_is_drawn(ablations: Path, tmp_path: Path) -> None:
    runs = [ablations / "runs" / method for method in METHODS]
    write_report(runs, tmp_path / "none", ReportConfig(pictures=PictureChoice.NONE, workers=1))
    drawn_before = {p.name for p in (ablations / "pictures").rglob("*_topdown.png")}
    none = {p.name for p in (tmp_path / "none").rglob("*_topdown.png")}
    assert none <= drawn_before  # only the pictures bench ablations had drawn
    write_report(runs, tmp_path / "one", ReportConfig(pictures=PictureChoice.ALL, max_pictures=1, workers=2))
    for method in METHODS:
        pictures = set((tmp_path / "one" / "runs" / method / "pictures").glob("*_topdown.png"))
        reused = {p for p in pictures if (ablations / "pictures" / method / p.name).is_file()}
        assert len(pictures - reused) <= 1


def test_the_pivot_lists_the_episodes_one_run_solved_and_the_other_did_not(ablations: Path) -> None:
    runs = [load_run(ablations / "runs" / m, m) for m in METHODS]
    success = {run.name: {r.episode_id: r.success for r in run.records} for run in runs}
    pairs = pivot_pairs(runs)
    for a, b in ((METHODS[0], METHODS[1]), (METHODS[1], METHODS[0])):
        assert pairs[(a, b)] == [i for i in success[a] if success[a][i] == 1 and success[b][i] == 0]


def test_a_single_run_has_no_paper_tables_and_no_differences(ablations: Path, tmp_path: Path) -> None:
    index = write_report([ablations / "runs" / "frontier"], tmp_path / "site", ReportConfig(workers=1))
    text = index.read_text(encoding="utf-8")
    assert "Table VI" not in text and "Settings that differ" not in text
    html5lib.HTMLParser(strict=True).parse(text)


def test_run_names_tell_folders_of_one_name_apart() -> None:
    paths = [Path("a/run"), Path("b/run"), Path("c/x"), Path("c/x")]
    assert run_names(paths) == ["a-run", "b-run", "c-x", "c-x-2"]
    grid = [Path("out/regimes/paper/runs/drive-nav"), Path("out/regimes/weak-detector/runs/drive-nav")]
    assert run_names([*grid, Path("out/regimes/paper/runs/vlfm")]) == [
        "paper-drive-nav",
        "weak-detector-drive-nav",
        "vlfm",
    ]


def test_config_differences_name_the_settings_that_are_not_the_same_in_every_run(ablations: Path) -> None:
    assert flatten({"a": {"b": 1, "c": [1, 2]}, "d": "x"}) == {"a.b": 1, "a.c": [1, 2], "d": "x"}
    runs = [load_run(ablations / "runs" / m, m) for m in METHODS]
    differences = config_differences(runs)
    assert {"run.agent", "agent.enrich", "agent.verify"} <= set(differences)
    assert "sim.max_steps" not in differences and "env.scenes" not in differences
    assert config_differences(runs[:1]) == []


def test_markdown_tables_headings_lists_and_code_become_html() -> None:
    text = "# Title\n\nSome `code` & text.\n\n## Table\n\n| a | b |\n|---|---|\n| `x` | 2 |\n\n- one\n- two\n"
    html = to_html(text, heading_shift=1)
    assert html.splitlines() == [
        "<h2>Title</h2>",
        "<p>Some <code>code</code> &amp; text.</p>",
        "<h3>Table</h3>",
        '<table><thead><tr><th scope="col">a</th><th scope="col">b</th></tr></thead>'
        "<tbody><tr><td><code>x</code></td><td>2</td></tr></tbody></table>",
        "<ul><li>one</li><li>two</li></ul>",
    ]
    assert "Table" not in to_html(text, leave_out=frozenset({"Table"}))


def test_long_timing_series_are_binned_by_their_mean() -> None:
    assert _binned([1.0, 2.0, 3.0, 4.0], 2).tolist() == [1.5, 3.5]
    assert _binned([1.0, 2.0], 5).tolist() == [1.0, 2.0]


def test_report_without_a_run_directory_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path / "missing"), "--out", str(tmp_path / "site")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "episodes.jsonl" in err
