"""Per-step timings: the columnar trace format and Table VII built from saved traces."""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivenav.agent.trace import DirectionSelected, StopEvent
from drivenav.eval.timings import from_columns, runtime_table, summary, to_columns, traced_steps
from drivenav.eval.trace import EpisodeTrace

MODULE_NAMES = st.sampled_from(["mapping", "directions.total", "directions.fmm", "inspection", "policy"])
MS = st.floats(min_value=0.0, max_value=1e4, allow_nan=False).map(lambda v: round(v, 3))


@given(st.lists(st.dictionaries(MODULE_NAMES, MS, min_size=1), max_size=30))
def test_columns_round_trip_with_missing_modules_as_zero(steps: list[dict[str, float]]) -> None:
    columns = to_columns(steps)
    assert all(len(values) == len(steps) for values in columns.values())
    back = from_columns(columns)
    assert len(back) == len(steps)
    for original, restored in zip(steps, back, strict=True):
        assert {k: v for k, v in restored.items() if k in original} == original
        assert all(v == 0.0 for k, v in restored.items() if k not in original)


def test_summary_median_p90_mean_by_hand() -> None:
    assert summary([4.0, 1.0, 3.0, 2.0, 10.0]) == {"median_ms": 3.0, "p90_ms": 4.0, "mean_ms": 4.0}


def test_runtime_table_sums_compute_modules_and_counts_decisions() -> None:
    steps = [
        {"mapping": 1.0, "directions.total": 10.0, "inspection": 0.5, "policy": 0.5, "grounding": 100.0},
        {"mapping": 2.0, "directions.total": 20.0, "inspection": 1.0, "policy": 1.0, "grounding": 100.0},
    ]
    table = runtime_table(steps, decisions=3, episodes=1, agent="drive-nav", width=640, height=480)
    assert table["steps"] == 2 and table["median_ms"] == 18.0  # (12 + 24) / 2: grounding is not compute
    assert table["modules"]["direction selection (reasoner)"]["invocations"] == 3
    with pytest.raises(ValueError, match="at least one"):
        runtime_table([], 0, 0, "drive-nav", 640, 480)


def test_traced_steps_skips_traces_without_timings() -> None:
    decision = DirectionSelected(1, 2, 0.5, (1.0, 2.0), (2, 3), "scan")
    untimed = EpisodeTrace("e", "s", ((0.0, 0.0),), (0.0,), events=(decision,))
    timed = replace(untimed, step_ms={"mapping": [1.0, 2.0]}, events=(decision, StopEvent(2, "done")))
    steps, decisions, episodes = traced_steps([timed, untimed, replace(untimed, step_ms={}), timed])
    assert len(steps) == 4 and decisions == 2 and episodes == 2
