"""The geometric stand-in reasoner: frontier extent discounted by travel distance, ties to the smallest turn."""

from __future__ import annotations

import math

import pytest

from drivenav.semantics.geometric import GeometricReasoner, direction_score
from drivenav.semantics.protocols import Candidate, Reasoner


def cand(label: int, cells: int, time: float = 2.0, turn: float = 0.0) -> Candidate:
    return Candidate(label=label, bearing=turn, turn=turn, travel_time=time, frontier_cells=cells)


def test_satisfies_reasoner_protocol() -> None:
    reasoner: Reasoner = GeometricReasoner()
    assert reasoner.name == "geometric"


def test_picks_the_bigger_frontier() -> None:
    selection = GeometricReasoner().select_direction("sofa", [cand(1, 40), cand(2, 90), cand(3, 60)])
    assert selection.label == 2
    assert not selection.target_visible and selection.target_label is None


def test_distance_discount() -> None:
    # Near: 60 / (1 + 1/5) = 50; far: 100 / (1 + 20/5) = 20.
    near, far = cand(1, 60, time=1.0), cand(2, 100, time=20.0)
    assert direction_score(near, 5.0) == pytest.approx(50.0)
    assert direction_score(far, 5.0) == pytest.approx(20.0)
    assert GeometricReasoner(distance_scale=5.0).select_direction("bed", [far, near]).label == 1
    # With a long distance scale the bigger frontier wins again: 60/1.01 < 100/1.2.
    assert GeometricReasoner(distance_scale=100.0).select_direction("bed", [far, near]).label == 2


def test_tie_goes_to_the_smaller_turn() -> None:
    # Equal scores; label 4 turns least but has one frontier cell fewer, so it loses on score.
    candidates = [cand(1, 50, turn=-1.2), cand(2, 50, turn=0.4), cand(3, 50, turn=-0.3), cand(4, 49, turn=0.1)]
    assert GeometricReasoner().select_direction("tv", candidates).label == 3
    assert GeometricReasoner().select_direction("tv", candidates[::-1]).label == 3


def test_equal_turns_go_to_the_smaller_label() -> None:
    candidates = [cand(7, 50, turn=-0.4), cand(5, 50, turn=0.4)]
    assert GeometricReasoner().select_direction("tv", candidates).label == 5
    assert GeometricReasoner().select_direction("tv", candidates[::-1]).label == 5


def test_unreachable_scores_zero() -> None:
    assert direction_score(cand(1, 500, time=math.inf), 5.0) == 0.0
    assert direction_score(cand(1, 500, time=math.nan), 5.0) == 0.0
    assert GeometricReasoner().select_direction("tv", [cand(1, 500, time=math.inf), cand(2, 3)]).label == 2


def test_no_candidates() -> None:
    selection = GeometricReasoner().select_direction("sofa", [])
    assert selection.label is None and not selection.target_visible


def test_rejects_bad_distance_scale() -> None:
    with pytest.raises(ValueError):
        GeometricReasoner(distance_scale=0.0)
