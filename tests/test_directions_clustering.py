"""Angular-gap clustering (Sec. IV-A b): hand-worked cases and invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from drivenav.directions.clustering import circular_distance, circular_mean, cluster_bearings

TAU = math.radians(45.0)


def _groups_in_degrees(bearings_deg: list[float]) -> list[list[float]]:
    groups = cluster_bearings(np.radians(bearings_deg), TAU)
    return [[bearings_deg[k] for k in g] for g in groups]


def test_bearings_straddling_zero_form_one_cluster() -> None:
    assert _groups_in_degrees([5.0, 180.0, 350.0, 20.0]) == [[350.0, 5.0, 20.0], [180.0]]
    assert math.degrees(circular_mean(np.radians([350.0, 5.0, 20.0]))) == pytest.approx(5.0, abs=1e-9)


def test_span_must_stay_strictly_below_tau() -> None:
    assert _groups_in_degrees([100.0, 144.9]) == [[100.0, 144.9]]
    assert _groups_in_degrees([100.0, 145.0 + 1e-9]) == [[100.0], [145.0 + 1e-9]]


def test_greedy_sweep_starts_after_the_largest_gap() -> None:
    # The 270-degree gap precedes 0, so the sweep goes 0, 30 | 60, 90 (not 30, 60 | 90 ...).
    assert _groups_in_degrees([60.0, 0.0, 90.0, 30.0]) == [[0.0, 30.0], [60.0, 90.0]]
    # Largest gap 120 -> 330 (210 deg): sweep 330, 350, 10 | 30 | 120; starting at the smallest bearing
    # instead would give 10, 30 | 120 | 330, 350.
    assert _groups_in_degrees([10.0, 120.0, 330.0, 30.0, 350.0]) == [[330.0, 350.0, 10.0], [30.0], [120.0]]


def test_degenerate_inputs() -> None:
    assert cluster_bearings([], TAU) == []
    assert [g.tolist() for g in cluster_bearings([2.0], TAU)] == [[0]]
    assert [g.tolist() for g in cluster_bearings([1.0, 1.0 + 2 * math.pi], TAU)] == [[0, 1]]


def test_circular_distance_wraps() -> None:
    assert circular_distance(math.radians(350), math.radians(10)) == pytest.approx(math.radians(20))
    assert circular_distance(0.0, math.pi) == pytest.approx(math.pi)
    assert circular_distance(-0.1, 0.1) == pytest.approx(0.2)


bearing_lists = st.lists(st.floats(0.0, 2 * math.pi, exclude_max=True), min_size=1, max_size=25)


def _span(angles: np.ndarray) -> float:
    """Counter-clockwise extent of angles given in sweep order."""
    return float(np.mod(angles[-1] - angles[0], 2 * math.pi)) if len(angles) > 1 else 0.0


def _partition(bearings: np.ndarray) -> set[frozenset[float]]:
    return {frozenset(np.round(bearings[g], 9).tolist()) for g in cluster_bearings(bearings, TAU)}


def _well_posed(bearings: np.ndarray) -> bool:
    """No tie for the largest gap and no pair within round-off of tau (either would make the split depend on
    float noise rather than geometry)."""
    b = np.sort(np.mod(bearings, 2 * math.pi))
    gaps = np.sort(np.diff(b, append=b[0] + 2 * math.pi))
    diffs = np.abs(np.mod(b[:, None] - b[None, :], 2 * math.pi) - TAU)
    return (len(b) == 1 or gaps[-1] - gaps[-2] > 1e-6) and bool((diffs > 1e-6).all())


@settings(max_examples=200, deadline=None)
@given(bearing_lists)
def test_every_cluster_spans_less_than_tau_and_covers_each_bearing_once(values: list[float]) -> None:
    bearings = np.array(values)
    groups = cluster_bearings(bearings, TAU)
    assert sorted(np.concatenate(groups).tolist()) == list(range(len(values)))
    for group in groups:
        assert _span(bearings[group]) < TAU


@settings(max_examples=200, deadline=None)
@given(bearing_lists, st.randoms(use_true_random=False))
def test_clustering_does_not_depend_on_input_order(values: list[float], rng: object) -> None:
    bearings = np.array(values)
    assume(_well_posed(bearings))
    shuffled = bearings.copy()
    rng.shuffle(shuffled)  # type: ignore[attr-defined]
    assert _partition(shuffled) == _partition(bearings)


@settings(max_examples=200, deadline=None)
@given(bearing_lists, st.floats(-10.0, 10.0))
def test_clustering_is_invariant_to_a_common_rotation(values: list[float], rotation: float) -> None:
    bearings = np.array(values)
    assume(_well_posed(bearings))
    rotated = np.mod(bearings + rotation, 2 * math.pi)
    groups = cluster_bearings(bearings, TAU)
    groups_rotated = cluster_bearings(rotated, TAU)
    assert {frozenset(g.tolist()) for g in groups} == {frozenset(g.tolist()) for g in groups_rotated}
