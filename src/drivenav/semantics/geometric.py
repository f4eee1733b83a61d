"""A geometry-only reasoner: the VLM-free stand-in for direction selection (Sec. IV-A c, IV-B).

DRIVE-Nav asks Qwen3-VL which persistent direction to explore next. Without a vision-language model, this
reasoner ranks the candidates by their unexplored extent discounted by how far away it is:

    score = frontier_cells / (1 + travel_time / distance_scale)

``travel_time`` is the weighted-FMM time (metres at unit speed), so ``distance_scale`` is the travel distance
that halves a direction's worth. An unreachable direction (infinite or NaN time) scores 0. Equal scores go to
the smallest ``|turn|`` and then the smallest label, so the choice is deterministic. It cannot see, so it never
reports the target as visible.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from drivenav.semantics.protocols import (
    FLOOR_KIND,
    HINTS_KIND,
    Candidate,
    CategoryHints,
    FloorJudgement,
    ModelCall,
    Proposal,
    Selection,
    Verdict,
    VerificationFrame,
    View,
)
from drivenav.types import GroundTruth

CONTINUATION_BONUS = 2.0  # the direction being followed counts this many times over (commitment)


def direction_score(candidate: Candidate, distance_scale: float) -> float:
    """Frontier extent discounted by travel distance (module docstring), times :data:`CONTINUATION_BONUS` for
    the direction being followed; 0 when unreachable."""
    if not math.isfinite(candidate.travel_time):
        return 0.0
    bonus = CONTINUATION_BONUS if candidate.current else 1.0
    return bonus * candidate.frontier_cells / (1.0 + max(candidate.travel_time, 0.0) / distance_scale)


class GeometricReasoner:
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` from candidate geometry alone."""

    name = "geometric"

    def __init__(self, distance_scale: float = 5.0) -> None:
        if not (math.isfinite(distance_scale) and distance_scale > 0.0):
            raise ValueError(f"distance_scale must be a positive finite number, got {distance_scale!r}")
        self.distance_scale = distance_scale
        self.calls: list[ModelCall] = []

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        self.calls = []

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        """The best-scoring candidate (``label=None`` when there is none); ``goal`` plays no part."""
        self.calls.append(ModelCall("select_direction", 0.0, "ok"))
        if not candidates:
            return Selection(label=None, note="no candidates")
        best = max(candidates, key=self._rank)
        score = direction_score(best, self.distance_scale)
        return Selection(label=best.label, note=f"geometric score {score:.2f}")

    def _rank(self, candidate: Candidate) -> tuple[float, float, int]:
        """Sort key, larger is better: score, then smaller |turn|, then smaller label."""
        return direction_score(candidate, self.distance_scale), -abs(candidate.turn), -candidate.label

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
        """It cannot see: the goal text itself."""
        self.calls.append(ModelCall("propose_prompt", 0.0, "ok"))
        return Proposal(goal)

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        """It cannot see: always uncertain, so a candidate is accepted after the last verification frame."""
        self.calls.append(ModelCall("verify", 0.0, "ok"))
        return Verdict("uncertain")

    def category_hints(self, goal: str) -> CategoryHints:
        """It knows no categories: no confusable objects, the middle threshold, any room."""
        self.calls.append(ModelCall(HINTS_KIND, 0.0, "ok"))
        return CategoryHints.unknown()

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        """It cannot see: unsure, so floors are changed only when one is explored."""
        self.calls.append(ModelCall(FLOOR_KIND, 0.0, "ok"))
        return FloorJudgement("unsure")
