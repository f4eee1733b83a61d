"""Run comparison: the Table II subset holds exactly the long episodes every method solved."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from drivenav.analysis.compare import Comparison, compare, format_comparison
from drivenav.eval.records import EpisodeRecord

DATA = Path(__file__).parent / "data" / "ablations"


def _run_dir(root: Path, name: str, rows: list[tuple[str, int, float, int, int]]) -> Path:
    out = root / name
    out.mkdir()
    with (out / "episodes.jsonl").open("w") as handle:
        for episode_id, success, d0, steps, revisits in rows:
            stop = "target_reached" if success else "timeout"
            record = EpisodeRecord(episode_id, "s", "chair", name, steps, revisits, stop, "" if success else stop)
            record = replace(record, success=success, spl=0.5 * success, geodesic_distance=d0, path_length=d0)
            handle.write(json.dumps(record.to_json()) + "\n")
    return out


def test_common_long_successes(tmp_path: Path) -> None:
    a = _run_dir(
        tmp_path, "a", [("0", 1, 12.0, 100, 0), ("1", 1, 15.0, 200, 1), ("2", 1, 5.0, 50, 0), ("3", 0, 20.0, 500, 2)]
    )
    b = _run_dir(
        tmp_path, "b", [("0", 1, 12.0, 150, 1), ("1", 0, 15.0, 500, 3), ("2", 1, 5.0, 60, 0), ("3", 1, 20.0, 300, 0)]
    )
    result = compare({"a": a, "b": b}, min_distance=10.0)
    assert result.common_episodes == 1  # only episode 0: long and solved by both
    common_a, common_b = result.methods["a"].common, result.methods["b"].common
    assert common_a is not None and common_a.avg_steps == 100
    assert common_b is not None and common_b.avg_steps == 150 and common_b.avg_revisits == 1
    assert result.methods["a"].overall.success_rate == 0.75
    assert "common (n=1" in format_comparison(result)
    assert Comparison.from_json(json.loads(json.dumps(result.to_json()))) == result


def test_the_comparison_reads_and_prints_as_before() -> None:
    """``ablations.json``'s ``table_ii`` (a comparison written before it was typed) reads back to the same JSON, and
    prints the table ``drivenav compare`` printed then."""
    table = json.loads((DATA / "ablations.json").read_text())["table_ii"]
    comparison = Comparison.from_json(table)
    assert comparison.to_json() == table
    assert json.dumps(comparison.to_json()) == json.dumps(table)  # the same keys in the same order
    assert format_comparison(comparison) + "\n" == (DATA / "compare.txt").read_text()
