"""``drivenav bench ablations`` and ``drivenav benchmark generate``; the confidence intervals behind the tables."""

from __future__ import annotations

import csv
import hashlib
import json
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.agent.base import ModelCounters
from drivenav.analysis.ablation_data import AblationReport, Runtime
from drivenav.analysis.ablation_report import format_markdown, ordering_differences
from drivenav.analysis.ablations import method_entry, model_call_latency, split_entries
from drivenav.analysis.stats import bootstrap_mean_interval, wilson_interval
from drivenav.benchmarks.benchmark import BENCHMARK_V1, BENCHMARK_V2, BenchmarkDefinition, generate_benchmark
from drivenav.cli import main
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.rosmap import is_map_scene_dir
from drivenav.eval.episodes import save_episodes, validate_for_scenes
from drivenav.eval.records import EpisodeRecord
from drivenav.methods import ALL_METHODS
from drivenav.types import SimConfig

METHOD_KEYS = {
    "episodes",
    "errors",
    "success_rate",
    "spl",
    "avg_steps",
    "avg_revisits",
    "avg_retraced_revisits",
    "median_vlm_calls",
    "missed_target_causes",
    "decisions",
    "sr_ci95",
    "spl_ci95",
    "vlm_calls",
    "avg_reasoner_calls",
    "median_reasoner_calls",
    "avg_scorer_calls",
    "median_scorer_calls",
    "failure_causes",
}
DATA = Path(__file__).parent / "data" / "ablations"
TINY = ["--episodes", "2", "--methods", "drive-nav,nearest-frontier", "--max-steps", "20", "--scenes", "procedural:1"]
MODELS = ["--reasoner", "geometric", "--detector", "ground-truth"]


def test_wilson_interval_matches_hand_computed_values() -> None:
    # 8 of 10: centre (0.8 + z^2/20) / (1 + z^2/10), half-width z sqrt(0.016 + z^2/400) / (1 + z^2/10).
    low, high = wilson_interval(8, 10)
    assert low == pytest.approx(0.4902, abs=1e-4)
    assert high == pytest.approx(0.9433, abs=1e-4)
    # 0 of 10 and 10 of 10: the interval ends at 0 (resp. 1) and reaches z^2 / (n + z^2) = 0.2775 inside.
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson_interval(10, 10) == pytest.approx((0.7225, 1.0), abs=1e-4)
    with pytest.raises(ValueError):
        wilson_interval(1, 0)


def test_bootstrap_interval_matches_hand_computed_values() -> None:
    # Two values 0 and 1: resampled means are 0, 0.5, 1 with probabilities 1/4, 1/2, 1/4, so the 2.5 % and 97.5 %
    # quantiles are 0 and 1.
    assert bootstrap_mean_interval([0.0, 1.0]) == (0.0, 1.0)
    assert bootstrap_mean_interval([0.25, 0.25, 0.25]) == pytest.approx((0.25, 0.25))
    values = [0.0, 0.1, 0.5, 0.9, 0.7, 0.0, 0.3]
    low, high = bootstrap_mean_interval(values)
    assert low < sum(values) / len(values) < high
    assert bootstrap_mean_interval(values) == (low, high)  # fixed seed
    with pytest.raises(ValueError):
        bootstrap_mean_interval([])


def test_ordering_differences_name_reversed_and_tied_pairs() -> None:
    paper = {"a": 1.0, "b": 2.0, "c": 3.0}
    assert ordering_differences(paper, {"a": 10.0, "b": 20.0, "c": 30.0}) == []
    differences = ordering_differences(paper, {"a": 10.0, "b": 30.0, "c": 20.0})
    assert len(differences) == 1 and differences[0].startswith("`b` is above `c`")
    assert "ties" in ordering_differences(paper, {"a": 5.0, "b": 5.0, "c": 6.0})[0]


def test_default_methods_cover_tables_ii_v_vi_once() -> None:
    expected = {"frontier", "directional", "directional-enrich", "directional-verify", "drive-nav"}
    expected |= {"no-weighted-fmm", "no-240", "direction-360", "nearest-frontier", "vlfm", "apexnav"}
    assert set(ALL_METHODS) == expected and len(ALL_METHODS) == len(expected)


def _line_counts(out: Path) -> dict[str, int]:
    return {d.name: len((d / "episodes.jsonl").read_text().splitlines()) for d in (out / "runs").iterdir()}


def test_bench_ablations_writes_tables_and_resumes(tmp_path: Path) -> None:
    out = tmp_path / "ablations"
    assert main(["bench", "ablations", *TINY, *MODELS, "--out", str(out)]) == 0
    report = json.loads((out / "ablations.json").read_text())
    assert {"methods", "table_ii", "runtime", "episodes", "seed", "commit"} <= set(report)
    assert "splits" not in report  # v1's episodes have no vocabulary split
    assert list(report["methods"]) == ["drive-nav", "nearest-frontier"]
    assert report["episodes"] == 2 and report["seed"] == BENCHMARK_V1.seed
    for entry in report["methods"].values():
        assert set(entry) == METHOD_KEYS
        for value, key in ((entry["success_rate"], "sr_ci95"), (entry["spl"], "spl_ci95")):
            low, high = entry[key]
            assert 0.0 <= low <= value <= high <= 1.0
        assert sum(entry["failure_causes"].values()) == 2 - round(2 * entry["success_rate"])
        assert sum(entry["missed_target_causes"].values()) == entry["failure_causes"]["missed_target"]
    assert set(report["table_ii"]["methods"]) == {"drive-nav", "nearest-frontier"}
    compute = report["runtime"]["compute"]
    assert compute["agent"] == "drive-nav" and compute["episodes"] == 2
    drive_nav = [json.loads(line) for line in (out / "runs" / "drive-nav" / "episodes.jsonl").read_text().splitlines()]
    assert compute["steps"] == sum(record["steps"] for record in drive_nav)  # every step of the run is timed
    assert 0.0 < compute["modules"]["directions: weighted FMM"]["median_ms"] <= compute["p90_ms"]
    rows = list(csv.DictReader((out / "ablations.csv").open()))
    assert [row["method"] for row in rows] == ["drive-nav", "nearest-frontier"]
    assert {"sr_ci95.lo", "spl_ci95.hi", "failure_causes.timeout"} <= set(rows[0])
    markdown = (out / "ablations.md").read_text()
    for heading in ("Table VI", "Table V:", "Table II", "Table VII", "Failure causes", "orderings differ"):
        assert heading in markdown
    assert "| ✓ | ✓ | ✓ | ✓ | `drive-nav` |" in markdown
    pictures = report["pictures"]["episodes"]
    assert len(pictures) == 2 and all(
        list(by_method) == ["drive-nav", "nearest-frontier"] for by_method in pictures.values()
    )
    for by_method in pictures.values():
        for path in by_method.values():
            assert (out / path).stat().st_size > 0 and f"]({path})" in markdown
    assert report["pictures"]["video"] == "pictures/drive-nav/0.mp4" and (out / "pictures/drive-nav/0.mp4").exists()
    before = {d: (out / "runs" / d / "episodes.jsonl").read_text() for d in _line_counts(out)}
    episodes_file = str(out / "episodes.json.gz")
    rerun = ["bench", "ablations", *TINY, *MODELS, "--out", str(out), "--episodes", episodes_file]
    assert main(rerun) == 0  # the same episodes from the file: everything is finished already
    assert _line_counts(out) == {"drive-nav": 2, "nearest-frontier": 2}
    assert {d: (out / "runs" / d / "episodes.jsonl").read_text() for d in before} == before


def test_bench_ablations_without_pictures(tmp_path: Path) -> None:
    out = tmp_path / "ablations"
    args = ["bench", "ablations", *TINY, *MODELS, "--methods", "nearest-frontier", "--pictures", "0"]
    assert main([*args, "--out", str(out)]) == 0
    assert not (out / "pictures").exists()
    assert "None drawn" in (out / "ablations.md").read_text()
    assert main([*args, "--pictures", "-1", "--out", str(out)]) == 2


def test_bench_ablations_refuses_another_episode_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ablations"
    args = ["bench", "ablations", *TINY, *MODELS, "--methods", "nearest-frontier", "--out", str(out)]
    assert main(args) == 0
    assert main([*args, "--episodes", "3"]) == 2
    assert "--episodes" in capsys.readouterr().err


def test_bench_ablations_rejects_an_unknown_method(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["bench", "ablations", *TINY, "--methods", "drive-nav,nope", "--out", str(tmp_path)]) == 2
    assert "'--methods'" in capsys.readouterr().err and not list(tmp_path.iterdir())


def test_benchmark_generation_is_deterministic(tmp_path: Path) -> None:
    small = BenchmarkDefinition(scenes="procedural:2", episodes=3, seed=5)
    first, second = tmp_path / "a.json.gz", tmp_path / "b.json.gz"
    save_episodes(generate_benchmark(small), first)
    save_episodes(generate_benchmark(small), second)
    assert first.read_bytes() == second.read_bytes()
    assert len({e.scene_id for e in generate_benchmark(small)}) == 2


def test_benchmark_generate_command_repeats_bytes(tmp_path: Path, maps_dir: Path) -> None:
    outputs = [tmp_path / "one.json.gz", tmp_path / "two.json.gz"]
    for path in outputs:
        assert main(["benchmark", "generate", "--version", "v1", "--episodes", "2", "--out", str(path)]) == 0
    assert outputs[0].read_bytes() == outputs[1].read_bytes()


def test_v1_covers_40_houses_and_every_packaged_floor_plan(maps_dir: Path) -> None:
    library = SceneLibrary(BENCHMARK_V1.scenes, BENCHMARK_V1.seed)
    houses = [s for s in library.scene_ids if s.startswith("procedural/")]
    assert len(houses) == 40
    plans = {d.name for d in maps_dir.iterdir() if is_map_scene_dir(d)}
    assert set(library.scene_ids) - set(houses) == plans and len(plans) == 9
    assert BENCHMARK_V1.episodes >= 200
    # the frozen episodes name the packaged plans by the ids they had when v1 was published
    assert {e.scene_id for e in generate_benchmark(BENCHMARK_V1)} == set(library.scene_ids)


def test_benchmark_v1_is_frozen_as_published(tmp_path: Path) -> None:
    path = tmp_path / "v1.json.gz"
    save_episodes(generate_benchmark(BENCHMARK_V1), path)
    assert hashlib.sha256(path.read_bytes()).hexdigest().startswith("3de8fb637e73")  # docs/benchmarks.md
    first = generate_benchmark(BENCHMARK_V1, 12)
    assert [e.episode_id for e in first] == [str(i) for i in range(12)]
    library = SceneLibrary(BENCHMARK_V1.scenes, BENCHMARK_V1.seed)
    validate_for_scenes(first, library, path, SimConfig())  # still valid in today's worlds


def test_a_methods_intervals_do_not_depend_on_the_order_its_records_finished_in() -> None:
    records = [
        EpisodeRecord(str(k), "s", "chair", "drive-nav", 10, 0, "timeout", "", success=k % 3 == 0, spl=(k % 7) / 7)
        for k in range(40)
    ]
    entries = [method_entry(order) for order in (records, records[::-1], records[1::2] + records[::2])]
    assert entries[0].spl_ci95 == entries[1].spl_ci95 == entries[2].spl_ci95


def test_bench_ablations_runs_benchmark_v2_and_reports_each_split(tmp_path: Path) -> None:
    out = tmp_path / "v2"
    tiny = ["--episodes", "3", "--methods", "nearest-frontier", "--max-steps", "20", "--scenes", "procedural:1"]
    assert main(["bench", "ablations", "--benchmark", "v2", *tiny, *MODELS, "--pictures", "0", "--out", str(out)]) == 0
    report = json.loads((out / "ablations.json").read_text())
    assert report["seed"] == BENCHMARK_V2.seed  # the benchmark's seed where --seed is not given
    assert list(report["splits"]) == ["val_seen", "val_seen_synonyms", "val_unseen"]
    for by_method in report["splits"].values():
        assert list(by_method) == ["nearest-frontier"] and by_method["nearest-frontier"]["episodes"] == 1
    markdown = (out / "ablations.md").read_text()
    assert "## Per split" in markdown and "| method | val_seen SR | val_seen SPL |" in markdown
    assert "Episodes per split: val_seen (1), val_seen_synonyms (1), val_unseen (1)." in markdown


def test_bench_ablations_refuses_an_unknown_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["bench", "ablations", "--benchmark", "v0", "--out", str(tmp_path)])
    assert stopped.value.code == 2 and "--benchmark" in capsys.readouterr().err


def test_split_entries_are_each_methods_results_on_each_splits_episodes() -> None:
    def record(k: int, success: bool, spl: float) -> EpisodeRecord:
        return EpisodeRecord(str(k), "s", "chair", "drive-nav", 10, 0, "timeout", "", success=success, spl=spl)

    runs = {"drive-nav": {str(k): record(k, k in (0, 1, 4), 0.5 if k in (0, 1, 4) else 0.0) for k in range(6)}}
    splits = {"0": "val_unseen", "1": "val_seen", "2": "val_seen", "3": "val_unseen", "4": "val_seen", "5": "other"}
    table = split_entries(runs, splits)
    assert list(table) == ["val_seen", "val_unseen", "other"]  # HM3D-OVON's splits first
    seen, unseen = table["val_seen"]["drive-nav"], table["val_unseen"]["drive-nav"]
    assert seen.episodes == 3 and seen.success_rate == pytest.approx(2 / 3) and seen.spl == pytest.approx(1 / 3)
    assert (unseen.episodes, unseen.success_rate, unseen.spl) == (2, 0.5, 0.25)
    assert table["other"]["drive-nav"].success_rate == 0.0
    assert split_entries(runs, {}) == {}


def test_model_calls_are_given_per_method_beside_their_pooled_rate() -> None:
    def record(k: int, method: str, scores: int) -> EpisodeRecord:
        stats = ModelCounters({"score": scores} if scores else {}, {"score": 2.0 * scores} if scores else {})
        return EpisodeRecord(str(k), "s", "chair", method, 10, 0, "timeout", "", stats=stats)

    runs = {
        "vlfm": {str(k): record(k, "vlfm", 300) for k in range(2)},
        "drive-nav-plus": {str(k): record(k, "drive-nav-plus", 30 + 10 * k) for k in range(2)},
        "drive-nav": {str(k): record(k, "drive-nav", 0) for k in range(2)},
    }
    score = model_call_latency(runs)["score"]
    assert (score.calls, score.calls_per_episode, score.mean_latency_ms) == (670, 167.5, 2.0)
    assert score.by_method == {"vlfm": 300.0, "drive-nav-plus": 35.0}  # drive-nav makes none
    stored = AblationReport.from_json(json.loads((DATA / "ablations.json").read_text(encoding="utf-8")))
    markdown = format_markdown(replace(stored, runtime=Runtime(None, {"score": score})))
    assert "| 167.50 per episode (`drive-nav-plus` 35.00, `vlfm` 300.00) |" in markdown
    alone = model_call_latency({"vlfm": runs["vlfm"]})["score"]
    assert "| 300.00 per episode |" in format_markdown(replace(stored, runtime=Runtime(None, {"score": alone})))
