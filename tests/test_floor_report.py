"""The floor groups of the ablation report and of ``drivenav compare`` (benchmark v3: docs/floors.md).

Ten hand-made episodes: three in a one-floor scene (no ``info["cross_floor"]``), three in a home of several storeys
with a goal on the start floor, four needing a floor change; three methods, the floors-off variant of ``drive-nav``
the reference. Every count and rate below is worked out by hand from the outcome tables. A v1 or v2 episode set
carries no floor information and leaves the stored report's files as they were, byte for byte.
"""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.analysis.ablation_data import AblationReport, Floors, Paired
from drivenav.analysis.ablation_report import format_markdown, write_csv
from drivenav.analysis.ablations import build_report, floor_entries, floor_groups, split_entries
from drivenav.analysis.compare import RunRecords, compare, format_comparison
from drivenav.analysis.floor_compare import compare_with_floors, format_floors
from drivenav.analysis.stats import bootstrap_mean_interval, wilson_interval
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.episode import Episode, ObjectGoal, ViewPoint, world_to_habitat, yaw_to_quaternion
from drivenav.eval.episodes import save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.rundir import EPISODES_COPY, EPISODES_FILE
from drivenav.eval.runner import RunSpec
from drivenav.report.paper_tables import paper_tables_html
from drivenav.report.runs import load_run
from drivenav.settings import load_settings

STORED = Path(__file__).parent / "data" / "ablations"
DATA = Path(__file__).parent / "data" / "floor-report"
REFERENCE = "drive-nav-floors-off"

CROSS = {
    "0": None,
    "1": None,
    "2": None,
    "3": False,
    "4": False,
    "5": False,
    "6": True,
    "7": True,
    "8": True,
    "9": True,
}
"""Each episode's ``info["cross_floor"]`` (None: the key is absent, a one-floor scene)."""

E = "error"
OUTCOMES: dict[str, dict[str, float | str]] = {
    # episode: SPL of a success, 0.0 a failure, "error" an episode an exception ended
    REFERENCE: {"0": 0.5, "1": 0.8, "2": 0.0, "3": 0.6, "4": 0.0, "5": 0.4, "6": 0.0, "7": 0.0, "8": 0.3, "9": 0.0},
    "drive-nav": {"0": 0.6, "1": 0.0, "2": 0.9, "3": 0.5, "4": 0.7, "5": 0.4, "6": 0.2, "7": 0.5, "8": 0.0, "9": E},
    "vlfm": {"0": 0.0, "1": 0.4, "2": 0.0, "3": 0.0, "4": 0.0, "5": 0.2, "6": 0.0, "7": 0.0, "8": 0.0, "9": 0.0},
}


def _episode(episode_id: str, cross: bool | None) -> Episode:
    info: dict[str, object] = {"geodesic_distance": 12.0}
    if cross is not None:
        info.update(start_floor=0, goal_floors=[1] if cross else [0], cross_floor=cross)
    q = yaw_to_quaternion(0.0)
    goal = ObjectGoal(1, "chair", world_to_habitat(1.0, 1.0), (ViewPoint(world_to_habitat(1.5, 1.0), q),))
    return Episode(episode_id, "storeys/home_00001", world_to_habitat(4.0, 4.0), q, "chair", (goal,), info)


def _record(method: str, episode_id: str, outcome: float | str) -> EpisodeRecord:
    error = outcome == E
    base = EpisodeRecord(episode_id, "storeys/home_00001", "chair", method, 100, 0, E if error else "timeout", "")
    if error:
        return replace(base, error="RuntimeError: x")
    spl = float(outcome)
    return replace(base, success=int(spl > 0), spl=spl, geodesic_distance=12.0, path_length=12.0)


EPISODES = [_episode(episode_id, cross) for episode_id, cross in CROSS.items()]
RUNS: RunRecords = {m: {i: _record(m, i, o) for i, o in outcomes.items()} for m, outcomes in OUTCOMES.items()}


def _floors(reference: str = REFERENCE) -> Floors:
    floors = floor_entries(RUNS, dict.fromkeys(RUNS, floor_groups(EPISODES)), reference)
    assert floors is not None
    return floors


def _stored() -> AblationReport:
    return AblationReport.from_json(json.loads((STORED / "ablations.json").read_text(encoding="utf-8")))


# ----------------------------------------------------------------------------------------------- the groups


def test_each_episode_is_in_the_group_its_floor_information_says() -> None:
    assert floor_groups(EPISODES) == {
        **dict.fromkeys("012", "one_floor"),
        **dict.fromkeys("345", "same_floor"),
        **dict.fromkeys("6789", "cross_floor"),
    }
    one_floor = [_episode(str(k), None) for k in range(3)]
    assert floor_groups(one_floor) == {}  # v1, v2: no floor groups at all
    assert floor_groups([_episode("0", None), replace(_episode("1", None), info={"cross_floor": "yes"})]) == {}


def test_the_groups_count_the_right_episodes_and_successes() -> None:
    floors = _floors()
    assert list(floors.groups) == ["one_floor", "same_floor", "cross_floor"]
    assert all(list(by_method) == list(OUTCOMES) for by_method in floors.groups.values())
    counts = {
        group: {m: (e.results.episodes, e.successes, e.results.errors) for m, e in by.items()}
        for group, by in floors.groups.items()
    }
    assert counts == {
        "one_floor": {REFERENCE: (3, 2, 0), "drive-nav": (3, 2, 0), "vlfm": (3, 1, 0)},
        "same_floor": {REFERENCE: (3, 2, 0), "drive-nav": (3, 3, 0), "vlfm": (3, 1, 0)},
        "cross_floor": {REFERENCE: (4, 1, 0), "drive-nav": (4, 2, 1), "vlfm": (4, 0, 0)},
    }
    assert [floors.size(group) for group in floors.groups] == [3, 3, 4]


def test_the_statistics_are_the_per_split_ones_computed_by_hand() -> None:
    cross = _floors().groups["cross_floor"]["drive-nav"].results
    # episodes 6, 7, 8 measured (9 ended in an error): SPLs 0.2, 0.5, 0.0 in episode order, 2 successes of 3
    assert (cross.success_rate, cross.spl) == (0.666667, 0.233333)
    assert cross.sr_ci95 == tuple(round(bound, 6) for bound in wilson_interval(2, 3))
    assert cross.spl_ci95 == tuple(round(bound, 6) for bound in bootstrap_mean_interval([0.2, 0.5, 0.0]))
    one_floor = _floors().groups["one_floor"][REFERENCE].results
    assert (one_floor.success_rate, one_floor.spl) == (0.666667, 0.433333)  # (0.5 + 0.8 + 0) / 3
    # the same machinery as the per-split table: a floor group's columns are a split's over the same episodes
    as_splits = split_entries(RUNS, floor_groups(EPISODES))
    assert {g: {m: e.results for m, e in by.items()} for g, by in _floors().groups.items()} == as_splits


def test_each_method_is_paired_with_the_reference_within_each_group() -> None:
    paired = _floors().paired
    assert paired == {
        "one_floor": {"drive-nav": Paired(REFERENCE, 3, 1, 1), "vlfm": Paired(REFERENCE, 3, 0, 1)},  # 2 / 1; 0
        "same_floor": {"drive-nav": Paired(REFERENCE, 3, 1, 0), "vlfm": Paired(REFERENCE, 3, 0, 1)},  # 4; 3
        "cross_floor": {"drive-nav": Paired(REFERENCE, 3, 2, 1), "vlfm": Paired(REFERENCE, 4, 0, 1)},  # 9 left out
    }
    default = _floors("drive-nav").paired["cross_floor"]  # the default reference: drive-nav, floors on
    assert default == {REFERENCE: Paired("drive-nav", 3, 1, 2), "vlfm": Paired("drive-nav", 3, 0, 2)}
    assert _floors("nope").paired == {}  # a reference not run: nothing paired, the groups all there
    assert list(_floors("nope").groups) == ["one_floor", "same_floor", "cross_floor"]


# ----------------------------------------------------------------------------------------------- the report


def test_the_report_holds_the_floor_groups_as_new_keys_only() -> None:
    floors = _floors()
    report = replace(_stored(), floors=floors)
    data = json.loads(json.dumps(report.to_json()))
    assert list(data)[-1] == "floors" and list(data["floors"]) == ["reference", "groups", "paired"]
    cross = floors.groups["cross_floor"]["drive-nav"].results
    assert cross.sr_ci95 is not None and cross.spl_ci95 is not None
    assert data["floors"]["groups"]["cross_floor"]["drive-nav"] == {
        "episodes": 4,
        "errors": 1,
        "success_rate": 0.666667,
        "spl": 0.233333,
        "sr_ci95": list(cross.sr_ci95),
        "spl_ci95": list(cross.spl_ci95),
        "successes": 2,
    }
    assert data["floors"]["paired"]["cross_floor"]["vlfm"] == {
        "reference": REFERENCE,
        "shared": 4,
        "wins": 0,
        "losses": 1,
    }
    assert AblationReport.from_json(data) == report
    stored = json.loads((STORED / "ablations.json").read_text(encoding="utf-8"))
    assert {key: value for key, value in data.items() if key != "floors"} == stored


def test_the_markdown_shows_cross_floor_results_in_rows_of_their_own() -> None:
    markdown = format_markdown(replace(_stored(), floors=_floors()))
    section = markdown.split("\n## Per floor group\n")[1].split("\n## ")[0]
    assert f"## Per floor group\n{section}" == (DATA / "floors.md").read_text(encoding="utf-8")
    assert markdown.index("## Per floor group") < markdown.index("## Table I: all methods")
    sr = "66.7 [{:.1f}, {:.1f}]".format(*(100 * bound for bound in wilson_interval(2, 3)))
    assert f"| cross floor | `drive-nav` | 4 | 2 | 1 | {sr} | 23.3 [" in section and "| 2 / 1 (3) |" in section
    assert f"| same floor | `{REFERENCE}` | 3 | 2 | 0 |" in section and section.count("| reference |") == 3
    assert "Episodes per floor group: one-floor homes (3), same floor (3), cross floor (4)." in section
    unpaired = format_markdown(replace(_stored(), floors=_floors("nope")))
    assert "cross floor (4). `nope` was not run." in unpaired and "| reference |" not in unpaired.split("Table I")[0]


def test_the_csv_gives_each_method_its_floor_groups_columns(tmp_path: Path) -> None:
    floors = _floors()
    methods = {name: _stored().methods["drive-nav"] for name in OUTCOMES}
    write_csv(replace(_stored(), methods=methods, floors=floors), tmp_path / "a.csv")
    rows = {row["method"]: row for row in csv.DictReader((tmp_path / "a.csv").open(encoding="utf-8"))}
    drive_nav, reference = rows["drive-nav"], rows[REFERENCE]
    assert drive_nav["floors.reference"] == REFERENCE
    assert (drive_nav["floors.cross_floor.successes"], drive_nav["floors.cross_floor.errors"]) == ("2", "1")
    assert (drive_nav["floors.cross_floor.wins"], drive_nav["floors.cross_floor.losses"]) == ("2", "1")
    assert drive_nav["floors.cross_floor.sr_ci95.lo"] == str(round(wilson_interval(2, 3)[0], 6))
    assert (reference["floors.one_floor.wins"], reference["floors.one_floor.shared"]) == ("", "")  # not 0
    groups = {group: {m: e for m, e in by.items() if m != "vlfm"} for group, by in floors.groups.items()}
    without_vlfm = replace(floors, groups=groups)
    write_csv(replace(_stored(), methods=methods, floors=without_vlfm), tmp_path / "b.csv")
    vlfm = next(row for row in csv.DictReader((tmp_path / "b.csv").open(encoding="utf-8")) if row["method"] == "vlfm")
    assert vlfm["floors.same_floor.episodes"] == "" and vlfm["floors.same_floor.sr_ci95.hi"] == ""  # no record: blank


@pytest.mark.parametrize("name", ["ablations", "variant"])
@pytest.mark.parametrize("info", [{}, {"split": "val_seen"}], ids=["v1", "v2"])
def test_episodes_without_floor_information_leave_the_stored_files_as_they_were(
    name: str, info: dict[str, object], tmp_path: Path
) -> None:
    episodes = [replace(_episode(i, None), info=dict(info)) for i in CROSS]
    floors = floor_entries(RUNS, dict.fromkeys(RUNS, floor_groups(episodes)))
    assert floors is None
    text = (STORED / f"{name}.json").read_text(encoding="utf-8")
    report = replace(AblationReport.from_json(json.loads(text)), floors=floors)
    assert json.dumps(report.to_json(), indent=2) + "\n" == text
    assert format_markdown(report) == (STORED / f"{name}.md").read_text(encoding="utf-8")
    write_csv(report, tmp_path / "out.csv")
    assert (tmp_path / "out.csv").read_bytes() == (STORED / f"{name}.csv").read_bytes()


def test_bench_ablations_refuses_a_floor_reference_it_does_not_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["bench", "ablations", "--methods", "frontier", "--floor-reference", "drive-nav", "--out", str(tmp_path)]
    assert main(args) == 2
    assert "'--floor-reference'" in capsys.readouterr().err and not list(tmp_path.iterdir())


def test_build_report_adds_the_floor_groups_only_for_episodes_with_floor_information(tmp_path: Path) -> None:
    spec = RunSpec(EmbeddedSpec("procedural:1", 0), load_settings("random"))
    dirs = {name: tmp_path / name for name in RUNS}
    plain = build_report(dirs, RUNS, spec, len(EPISODES), {}, floor_groups([_episode(i, None) for i in CROSS]))
    assert plain.floors is None and "floors" not in plain.to_json()
    report = build_report(dirs, RUNS, spec, len(EPISODES), {}, floor_groups(EPISODES), REFERENCE)
    assert report.floors == _floors()
    assert replace(report, floors=None).to_json() == plain.to_json()  # nothing else changes


# ----------------------------------------------------------------------------------------------- compare, HTML


def _run_dir(root: Path, method: str, episodes: list[Episode]) -> Path:
    out = root / method
    out.mkdir(parents=True)
    lines = (json.dumps(record.to_json()) + "\n" for record in RUNS[method].values())
    (out / EPISODES_FILE).write_text("".join(lines), encoding="utf-8")
    save_episodes(episodes, out / EPISODES_COPY)
    return out


def test_compare_shows_the_floor_groups_of_each_runs_own_episodes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dirs = [_run_dir(tmp_path, method, EPISODES) for method in OUTCOMES]
    assert main(["compare", *map(str, dirs), "--floor-reference", REFERENCE]) == 0
    text = capsys.readouterr().out
    comparison = compare({d.name: d for d in dirs})
    assert text == f"{format_comparison(comparison)}\n\n{(DATA / 'compare.txt').read_text(encoding='utf-8')}"
    assert main(["compare", *map(str, dirs), "--floor-reference", REFERENCE, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {key: value for key, value in data.items() if key != "floors"} == comparison.to_json()
    assert Floors.from_json(data["floors"]) == _floors()
    assert main(["compare", *map(str, dirs), "--floor-reference", "nope"]) == 2
    assert "--floor-reference" in capsys.readouterr().err
    assert main(["compare", *map(str, dirs)]) == 0  # drive-nav is the default reference, run here
    assert "wins / losses vs drive-nav (episodes)" in capsys.readouterr().out
    assert format_floors(_floors("nope")).splitlines()[0].endswith("wins / losses vs nope (not run)")
    # a run over the same episodes without their floor information has no floor groups: it is left out of them
    _run_dir(tmp_path / "other", "vlfm", [_episode(i, None) for i in CROSS])
    mixed = {**{d.name: d for d in dirs[:2]}, "vlfm": tmp_path / "other" / "vlfm"}
    _, floors = compare_with_floors(mixed, 10.0, REFERENCE)
    assert floors is not None and all("vlfm" not in by_method for by_method in floors.groups.values())


def test_compare_of_runs_without_floor_information_prints_what_it_printed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dirs = [_run_dir(tmp_path, method, [_episode(i, None) for i in CROSS]) for method in OUTCOMES]
    comparison = compare({d.name: d for d in dirs})
    assert main(["compare", *map(str, dirs)]) == 0
    assert capsys.readouterr().out == format_comparison(comparison) + "\n"
    assert main(["compare", *map(str, dirs), "--json"]) == 0
    assert capsys.readouterr().out == json.dumps(comparison.to_json()) + "\n"


def test_the_reports_ablation_page_shows_the_floor_groups(tmp_path: Path) -> None:
    runs = [load_run(_run_dir(tmp_path / "runs", method, EPISODES), method) for method in OUTCOMES]
    report = replace(_stored(), methods={run.name: run.entry for run in runs}, floors=_floors())
    (tmp_path / "ablations.json").write_text(json.dumps(report.to_json()), encoding="utf-8")
    html = paper_tables_html(runs)
    assert html is not None and "Per floor group" in html
    assert "<td>cross floor</td><td><code>drive-nav</code></td><td>4</td><td>2</td><td>1</td>" in html
