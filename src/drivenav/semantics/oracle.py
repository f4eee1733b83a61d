"""The oracle reasoner and scorer: every question the VLM (Sec. IV-A c, IV-B, IV-C) and the image-text scorer of the
VLFM and ApexNav baselines answer, answered from the world's ground truth (docs/regimes.md).

They bound what better reasoning could give an exploration method: with the exact detector, what is left of a
method's failures is its exploration's. Both read privileged inputs, the instance labels (``semantic``) and the
episode's geodesic distance to the nearest goal (``geodesic``), so their records say so, as the oracle agent's do.

* Which direction next: a direction whose view shows a goal instance (``min_pixels`` of its category's pixels) is
  chosen outright, as the paper's VLM is asked to (the largest such view); else the direction whose frontier lies
  nearest the nearest goal by geodesic distance (the smallest over its frontier waypoints and farthest point,
  :attr:`~drivenav.semantics.protocols.Candidate.frontiers`). Ties go to the smaller ``|turn|``, then the smaller
  label. Without a geodesic distance (a world that cannot give one) it answers as the embedded reasoner.
* Is the target in view: the truth, from the view's instance image.
* Prompt enrichment: the goal's category name, then its synonyms, skipping the phrases tried.
* Verification: "sure" where the majority instance under the mask is of the goal's category, else "not" ("uncertain"
  without an instance image).
* ApexNav's category question: the embedded reasoner's confusable objects and threshold, and the room type that
  holds most of the category's objects in the world (the vocabulary's room shares), "everywhere" where it knows none.
* The floor question: ``this`` where a goal's view point lies within :data:`~drivenav.episode.HALF_STOREY` (1.2 m)
  of the height the floor's views were taken at, else ``other`` (the goals' heights are part of the geodesic ground
  truth); "unsure" without views or without a geodesic ground truth. It says a floor has no goal, not which way the
  goals are.
* The scorer (VLFM's and ApexNav's frame value): how much nearer the nearest goal the camera's line of sight leads,
  ``max over r of (d(pose) - d(pose + r * heading)) / r`` for ``r`` in :data:`REACH` (metres), clipped to [0, 1]: 1
  looking along the geodesic, 0 looking away or at a wall.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from drivenav.episode import HALF_STOREY
from drivenav.instances import instance_areas
from drivenav.semantics.embedded import EmbeddedReasoner, goal_phrases, label_under_mask, normalize_phrase
from drivenav.semantics.protocols import (
    EVERYWHERE,
    Candidate,
    CategoryHints,
    FloorGuess,
    FloorJudgement,
    Judgement,
    ModelCall,
    ScorePrompt,
    Selection,
    VerificationFrame,
    View,
    category_key,
)
from drivenav.types import GeodesicOracle, GroundTruth, Observation, Pose

REACH = (0.5, 1.0, 1.5, 2.0)
"""The distances along the line of sight (metres) at which the oracle scorer measures the geodesic's drop."""


class OracleReasoner(EmbeddedReasoner):
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` from the ground truth (module docstring)."""

    name = "oracle"

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        super().begin_episode(goal, truth)
        self._geodesic = truth.geodesic if truth is not None else None

    def _select(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        if not candidates:
            return Selection(label=None, note="no candidates")
        areas = [(self._target_area(goal, c.view), c) for c in candidates]
        showing = [(area, c) for area, c in areas if area > 0]
        if showing:
            best = max(showing, key=lambda item: (item[0], *self._tie_break(item[1])))[1]
            note = f"target seen in direction {best.label}"
            return Selection(label=best.label, target_visible=True, target_label=best.label, note=note)
        if self._geodesic is None:
            return super()._select(goal, candidates)
        distances = [(goal_distance(self._geodesic, c.frontiers), c) for c in candidates]
        distance, best = min(distances, key=lambda item: (item[0], abs(item[1].turn), item[1].label))
        return Selection(label=best.label, note=f"frontier {distance:.2f} m from the goal by geodesic")

    def _target_area(self, goal: str, view: View | None) -> int:
        """Pixels of the goal's category in a view (0 under ``min_pixels`` or without an instance image)."""
        semantic = view.semantic if view is not None else None
        if semantic is None:
            return 0
        wanted = category_key(goal, self._truth)
        area = sum(
            count
            for instance, count in instance_areas(semantic).items()
            if instance in self._labels and category_key(self._labels[instance], self._truth) == wanted
        )
        return area if area >= self.config.min_pixels else 0

    def _propose(self, goal: str, view: View, failed: Sequence[str]) -> str:
        tried = {normalize_phrase(phrase) for phrase in failed}
        return next((p for p in goal_phrases(goal, self._truth) if normalize_phrase(p) not in tried), goal)

    def _judge(self, goal: str, frame: VerificationFrame) -> Judgement:
        if frame.semantic is None:
            return "uncertain"
        label = label_under_mask(frame.semantic, frame.mask, self._labels)
        same = label is not None and category_key(label, self._truth) == category_key(goal, self._truth)
        return "sure" if same else "not"

    def _hints(self, goal: str) -> CategoryHints:
        hints = super()._hints(goal)
        vocabulary = self._truth.vocabulary if self._truth is not None else None
        shares = vocabulary.room_shares(category_key(goal, self._truth)) if vocabulary is not None else {}
        room = max(shares.items(), key=lambda item: (item[1], item[0]))[0] if shares else EVERYWHERE
        return CategoryHints(hints.similar, hints.threshold, room)

    def _floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        if self._geodesic is None or not views:
            return FloorJudgement("unsure", note="no goal heights" if views else "no views")
        height = self._geodesic.start_pose.z + views[-1].pose.z
        nearest = min((abs(goal_height - height) for goal_height in self._geodesic.goal_heights), default=math.inf)
        guess: FloorGuess = "this" if nearest <= HALF_STOREY else "other"
        return FloorJudgement(guess, note=f"the nearest goal view point {nearest:.2f} m above or below the floor")


def goal_distance(geodesic: GeodesicOracle, frontiers: Sequence[Pose]) -> float:
    """The smallest geodesic distance to the nearest goal from episode-frame ``frontiers`` (inf where none is
    reachable or none is given)."""
    start = geodesic.start_pose
    found = [geodesic.distance(start.compose(point)) for point in frontiers]
    return min((d for d in found if math.isfinite(d)), default=math.inf)


class OracleScorer:
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` from the geodesic distance (module
    docstring); 0 for a world without one."""

    name = "oracle"

    def __init__(self) -> None:
        self.calls: list[ModelCall] = []
        self._geodesic: GeodesicOracle | None = None

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.calls = []
        self._geodesic = truth.geodesic if truth is not None else None

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        self.calls.append(ModelCall("score", 0.0, "ok"))
        if self._geodesic is None:
            return 0.0
        return sight_progress(self._geodesic, self._geodesic.start_pose.compose(observation.pose))


def sight_progress(geodesic: GeodesicOracle, pose: Pose) -> float:
    """How much nearer the goal the line of sight from world-frame ``pose`` leads (module docstring), in [0, 1]."""
    here = geodesic.distance(pose)
    if not math.isfinite(here):
        return 0.0
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    drops = [(here - geodesic.distance(Pose(pose.x + r * c, pose.y + r * s, pose.yaw, pose.z))) / r for r in REACH]
    best = max((drop for drop in drops if math.isfinite(drop)), default=0.0)
    return min(max(best, 0.0), 1.0)
