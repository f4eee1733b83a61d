"""Per-step module timings: how a run stores them and the paper's Table VII built from them.

Every episode trace keeps the agent's per-step latencies in ``step_ms``, one column per module
(``{"mapping": [..], "directions.fmm": [..], ...}``, milliseconds, one value per step). Table VII (paper
Sec. V-E, runtime) is then computed from the very episodes of a benchmark run rather than a separate pass.

Compute per step = mapping + directions + inspection + the value-map update (VLFM, ApexNav) + target-centric fusion
(ApexNav) + policy; model calls (grounding, reasoning, the image-text scorer) are reported separately, as latency
per call and calls per episode. The value map's, the scorer's and fusion's rows appear only for agents that time
them.
"""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Mapping, Sequence

from drivenav.agent.trace import DirectionSelected, of_type
from drivenav.eval.trace import EpisodeTrace, StepColumns
from drivenav.jsonstream import JsonObject

COMPUTE_KEYS = ("mapping", "directions.total", "inspection", "value_map", "fusion", "policy")
MODULES = {
    "mapping (depth -> maps, frontiers)": "mapping",
    "directions: distance transforms": "directions.distance_transforms",
    "directions: skeleton": "directions.skeleton",
    "directions: weighted FMM": "directions.fmm",
    "directions: backtracking + bearings": "directions.backtracking",
    "directions: clustering": "directions.clustering",
    "directions: tracking": "directions.tracking",
    "inspection (representative views)": "inspection",
    "policy (planner, inspection events, decisions)": "policy",
    "grounding (detector, model)": "grounding",
}
VALUE_MODULES = {
    "value map (score -> FOV cone, fusion)": "value_map",
    "image-text scorer (model)": "scorer",
    "target-centric fusion (objects, negative evidence)": "fusion",
}
"""VLFM's and ApexNav's modules: rows of the table only where a step timed them."""


def to_columns(steps: Sequence[Mapping[str, float]]) -> StepColumns:
    """Per-step timing dicts as columns (a module missing at a step counts 0 ms), rounded to 1 us."""
    keys = sorted({key for step in steps for key in step})
    return {key: [round(step.get(key, 0.0), 3) for step in steps] for key in keys}


def from_columns(columns: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """The inverse of :func:`to_columns`."""
    length = max((len(values) for values in columns.values()), default=0)
    return [{key: values[i] for key, values in columns.items() if i < len(values)} for i in range(length)]


def summary(values: Sequence[float]) -> dict[str, float]:
    """Median, 90th percentile (nearest rank below) and mean of a non-empty sample, in ms."""
    ordered = sorted(values)
    return {
        "median_ms": round(statistics.median(ordered), 3),
        "p90_ms": round(ordered[int(0.9 * (len(ordered) - 1))], 3),
        "mean_ms": round(statistics.fmean(ordered), 3),
    }


def runtime_table(
    steps: Sequence[dict[str, float]], decisions: int, episodes: int, agent: str, width: int, height: int
) -> JsonObject:
    """Table VII from per-step timings: compute per step, and each module's latency and invocations."""
    if not steps:
        raise ValueError("runtime_table needs at least one timed step")
    compute = [sum(step.get(key, 0.0) for key in COMPUTE_KEYS) for step in steps]
    timed = {key for step in steps for key in step}
    rows = {**MODULES, **{name: key for name, key in VALUE_MODULES.items() if key in timed}}
    modules: dict[str, JsonObject] = {
        name: {**summary([s.get(key, 0.0) for s in steps]), "invocation": "every step"} for name, key in rows.items()
    }
    modules["direction selection (reasoner)"] = {"invocations": decisions, "invocation": "decision points"}
    return {
        "agent": agent,
        "width": width,
        "height": height,
        "episodes": episodes,
        "steps": len(steps),
        **summary(compute),
        "modules": modules,
    }


def traced_steps(traces: Iterable[EpisodeTrace]) -> tuple[list[dict[str, float]], int, int]:
    """All timed steps, decisions (:class:`~drivenav.agent.trace.DirectionSelected` events) and timed episodes in
    saved traces (traces without timings, written before ``step_ms`` existed, are skipped)."""
    steps: list[dict[str, float]] = []
    decisions = episodes = 0
    for trace in traces:
        if not trace.step_ms:
            continue
        steps.extend(from_columns(trace.step_ms))
        decisions += len(of_type(trace.events, DirectionSelected))
        episodes += 1
    return steps, decisions, episodes
