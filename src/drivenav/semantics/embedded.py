"""The embedded reasoner: Qwen3-VL's three questions answered from what the views show (Sec. IV-A c, IV-B, IV-C).

It stands in for the vision-language model in the embedded world. What it "recognises" in an image is exactly
the set of instances visible in that image's ``semantic`` channel, named through the episode's
ground truth's instance labels (:class:`~drivenav.types.GroundTruth`, given to
:meth:`EmbeddedReasoner.begin_episode` because it asks for ``semantic``), with their pixel areas; it uses no
other scene knowledge. Meaning comes from a real sentence-embedding model
(:class:`~drivenav.semantics.embedding.TextEmbedder`, all-MiniLM-L6-v2).

Relatedness of a label to the goal: 1 when both resolve to the same category of the world's vocabulary
(:func:`~drivenav.semantics.protocols.category_key`, so "couch" is the goal "sofa"), else the cosine
similarity of their embeddings. With the :class:`EmbeddedReasonerConfig` parameters:

* a label is *visible* in an image when its instances cover at least ``min_pixels`` pixels together;
* it *is the target* when its relatedness is at least ``sure_similarity`` (0.85 admits "office chair" for
  "chair" and rejects "towel rack" for "towel");
* direction selection (Sec. IV-A c) scores a candidate by ``semantic + exploration``:

  - ``semantic`` = max over the view's visible labels of ``ramp(relatedness) * area_weight(share)``, where
    ``ramp(r) = clip((r - unrelated_similarity) / (1 - unrelated_similarity), 0, 1)`` ignores the similarity
    level unrelated household words share, and ``area_weight(s) = area_floor + (1 - area_floor) * s /
    (s + area_half_share)`` for the label's share ``s`` of the image (a small glimpse still counts
    ``area_floor``);
  - ``exploration`` = ``exploration_weight * g / (g + exploration_half)`` with ``g`` the geometric reasoner's
    :func:`~drivenav.semantics.geometric.direction_score` (frontier cells discounted by travel distance over
    ``distance_scale``), so an empty corridor is worth something but less than a view of a related object.

  A direction whose view shows the target is chosen outright (the one with the largest target area), as the
  VLM is asked to return the target-bearing direction (Sec. IV-B). Ties go to the smaller ``|turn|``, then the
  smaller label;
* prompt proposal (Sec. IV-B) names the visible label most related to the goal when its relatedness is at least
  ``uncertain_similarity``, skipping failed phrases; otherwise the goal's category name or a synonym not tried;
* verification (Sec. IV-C) reads the label under the mask (the majority instance inside it): relatedness
  ``>= sure_similarity`` is "sure", ``>= uncertain_similarity`` "uncertain" (0.75 puts "mini fridge" for
  "refrigerator" here and "chair" for "armchair" below it), else "not"; background under the mask is "not";
  without a semantic image it cannot tell and answers "uncertain";
* ApexNav's category question (:meth:`EmbeddedReasoner.category_hints`, asked with the goal alone) is answered
  from the embeddings of the world's vocabulary (the episode's ground truth): the confusable objects are the
  ``similar_objects`` categories nearest the goal's category (cosine of their names; the goal's own category
  left out); the threshold rises over :data:`~drivenav.semantics.protocols.HINT_THRESHOLDS` with how close the
  nearest one is, ``lo + (hi - lo) * ramp(s_nearest)``, as ApexNav's LLM gives easily confused objects the higher
  thresholds (bed 0.65, apple 0.25); the room is the world's room type nearest the goal when its cosine is at least
  ``room_similarity`` (0.5: "bathroom" for a toilet at 0.79, "kitchen" for a refrigerator at 0.50; a sofa's 0.48
  is "everywhere"), else "everywhere". Without a vocabulary it knows nothing
  (:meth:`~drivenav.semantics.protocols.CategoryHints.unknown`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from drivenav.instances import instance_areas
from drivenav.semantics.embedding import TextEmbedder, default_embedder
from drivenav.semantics.geometric import direction_score
from drivenav.semantics.protocols import (
    EVERYWHERE,
    FLOOR_KIND,
    HINT_THRESHOLDS,
    HINTS_KIND,
    MAX_SIMILAR_OBJECTS,
    Candidate,
    CategoryHints,
    FloorJudgement,
    Judgement,
    ModelCall,
    Proposal,
    Selection,
    Verdict,
    VerificationFrame,
    View,
    category_key,
)
from drivenav.types import CategoryVocabulary, GroundTruth

_T = TypeVar("_T")


def label_areas(semantic: NDArray[np.int32], labels: Mapping[int, str], min_pixels: int) -> list[tuple[str, int]]:
    """The visible labels and their pixel areas (instances of one label summed), largest first, then by name."""
    areas: dict[str, int] = {}
    for instance, count in instance_areas(semantic).items():
        if instance in labels:
            areas[labels[instance]] = areas.get(labels[instance], 0) + count
    visible = [(label, count) for label, count in areas.items() if count >= min_pixels]
    return sorted(visible, key=lambda item: (-item[1], item[0]))


def label_under_mask(semantic: NDArray[np.int32], mask: NDArray[np.bool_], labels: Mapping[int, str]) -> str | None:
    """The label of the majority instance under ``mask`` (None for background, an empty mask or an unlabelled id)."""
    inside = semantic[mask]
    if inside.size == 0:
        return None
    ids, counts = np.unique(inside, return_counts=True)
    return labels.get(int(ids[int(np.argmax(counts))]))


def normalize_phrase(phrase: str) -> str:
    """Lower case, single spaces: how phrases are compared with the failed ones."""
    return " ".join(phrase.lower().split())


@dataclass(frozen=True)
class EmbeddedReasonerConfig:
    """The embedded reasoner's parameters (module docstring)."""

    min_pixels: int = 150
    sure_similarity: float = 0.85
    uncertain_similarity: float = 0.75
    unrelated_similarity: float = 0.3
    area_floor: float = 0.5
    area_half_share: float = 0.02
    exploration_weight: float = 0.3
    exploration_half: float = 40.0
    distance_scale: float = 5.0
    similar_objects: int = 4
    room_similarity: float = 0.5
    floor_rooms: int = 3
    floor_passages: tuple[str, ...] = ("hallway",)
    floor_together: tuple[str, ...] = ("kitchen", "living room", "dining room", "garage")
    floor_everywhere: tuple[str, ...] = ("bathroom",)
    floor_this: float = 0.5
    floor_other: float = 0.15
    room_evidence: float = 0.5

    def __post_init__(self) -> None:
        if self.min_pixels < 1:
            raise ValueError(f"min_pixels must be >= 1, got {self.min_pixels}")
        if not -1.0 <= self.unrelated_similarity < self.uncertain_similarity <= self.sure_similarity <= 1.0:
            raise ValueError("need -1 <= unrelated_similarity < uncertain_similarity <= sure_similarity <= 1")
        if not 0.0 <= self.area_floor <= 1.0:
            raise ValueError(f"area_floor must be in [0, 1], got {self.area_floor}")
        for name in ("area_half_share", "exploration_half", "distance_scale"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        if self.exploration_weight < 0.0:
            raise ValueError(f"exploration_weight must be >= 0, got {self.exploration_weight}")
        if not 0 <= self.similar_objects <= MAX_SIMILAR_OBJECTS:
            raise ValueError(f"similar_objects must be in [0, {MAX_SIMILAR_OBJECTS}], got {self.similar_objects}")


def relatedness(label: str, goal: str, truth: GroundTruth | None, embedder: TextEmbedder) -> float:
    """How related a label is to the goal: 1 for the goal's own category (``truth``'s vocabulary), else the cosine
    similarity of the two texts' embeddings."""
    if category_key(label, truth) == category_key(goal, truth):
        return 1.0
    return embedder.similarity(normalize_phrase(label), normalize_phrase(goal))


def semantic_value(related: Sequence[tuple[float, float]], config: EmbeddedReasonerConfig) -> float:
    """The ``semantic`` term of a view (module docstring): the max over its visible labels, given as
    ``(relatedness, share of the image)``, of ``ramp(relatedness) * area_weight(share)``; 0 with none visible."""
    return max((_ramp(r, config) * _area_weight(share, config) for r, share in related), default=0.0)


def _ramp(related: float, config: EmbeddedReasonerConfig) -> float:
    floor = config.unrelated_similarity
    return min(max((related - floor) / (1.0 - floor), 0.0), 1.0)


def _area_weight(share: float, config: EmbeddedReasonerConfig) -> float:
    return config.area_floor + (1.0 - config.area_floor) * share / (share + config.area_half_share)


@dataclass(frozen=True)
class _Assessment:
    """What one candidate's view shows, as the reasoner judged it."""

    candidate: Candidate
    score: float
    target_area: int
    description: str | None


class EmbeddedReasoner:
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` from the views' instance labels (module docstring)."""

    name = "embedded"

    def __init__(self, embedder: TextEmbedder | None = None, config: EmbeddedReasonerConfig | None = None) -> None:
        self._embedder = embedder
        self.config = config or EmbeddedReasonerConfig()
        self.calls: list[ModelCall] = []
        self._labels: dict[int, str] = {}
        self._truth: GroundTruth | None = None

    @property
    def embedder(self) -> TextEmbedder:
        """The embedding model (the shared default, loaded on first use, unless one was given)."""
        if self._embedder is None:
            self._embedder = default_embedder()
        return self._embedder

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        self.calls = []
        self._truth = truth
        self._labels = dict(truth.labels or {}) if truth is not None else {}

    def relatedness(self, label: str, goal: str) -> float:
        """1 for the goal's own category, else the cosine similarity of the two texts."""
        return relatedness(label, goal, self._truth, self.embedder)

    def visible(self, semantic: NDArray[np.int32] | None) -> list[tuple[str, int]]:
        """What an image shows: its visible labels and their areas, largest first (nothing without semantics)."""
        return [] if semantic is None else label_areas(semantic, self._labels, self.config.min_pixels)

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        """The target-bearing direction if a view shows the target, else the best ``semantic + exploration``."""
        return self._timed("select_direction", lambda: self._select(goal, candidates))

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
        """The visible target-like label most related to the goal, else the goal's category or a synonym.

        ``description`` adds nothing here: it was made from the same labels the view's semantic image holds.
        """
        return self._timed("propose_prompt", lambda: Proposal(self._propose(goal, view, failed)))

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        """Judge the label under the mask (earlier frames add nothing: each frame's labels are exact)."""
        return self._timed("verify", lambda: Verdict(self._judge(goal, frame)))

    def category_hints(self, goal: str) -> CategoryHints:
        """The nearest categories, a threshold from how near they are, the nearest room (module docstring)."""
        return self._timed(HINTS_KIND, lambda: self._hints(goal))

    def _timed(self, kind: str, answer: Callable[[], _T]) -> _T:
        start = time.perf_counter()
        result = answer()
        self.calls.append(ModelCall(kind, (time.perf_counter() - start) * 1000.0, "ok"))
        return result

    def _select(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        if not candidates:
            return Selection(label=None, note="no candidates")
        shown = [self.visible(c.view.semantic) if c.view is not None else [] for c in candidates]
        assessed = [self._assess(goal, c, labels) for c, labels in zip(candidates, shown, strict=True)]
        showing = [a for a in assessed if a.target_area > 0]
        descriptions = {a.candidate.label: a.description for a in assessed if a.description is not None}
        if showing:
            best = max(showing, key=lambda a: (a.target_area, *self._tie_break(a.candidate)))
            return Selection(
                label=best.candidate.label,
                target_visible=True,
                target_label=best.candidate.label,
                descriptions=descriptions,
                note=f"target seen in direction {best.candidate.label}",
            )
        best = max(assessed, key=lambda a: (a.score, *self._tie_break(a.candidate)))
        return Selection(label=best.candidate.label, descriptions=descriptions, note=f"embedded score {best.score:.2f}")

    @staticmethod
    def _tie_break(candidate: Candidate) -> tuple[float, int]:
        return -abs(candidate.turn), -candidate.label

    def _assess(self, goal: str, candidate: Candidate, shown: list[tuple[str, int]]) -> _Assessment:
        exploration = self._exploration(candidate)
        view = candidate.view
        if view is None:
            return _Assessment(candidate, exploration, 0, None)
        pixels = view.semantic.size if view.semantic is not None else 1
        related = [(self.relatedness(label, goal), area / pixels, area) for label, area in shown]
        semantic = semantic_value([(r, share) for r, share, _ in related], self.config)
        target_area = max((area for r, _, area in related if r >= self.config.sure_similarity), default=0)
        names = ", ".join(label for label, _ in shown) or "nothing recognisable"
        return _Assessment(candidate, semantic + exploration, target_area, f"shows: {names}")

    def _exploration(self, candidate: Candidate) -> float:
        c = self.config
        worth = direction_score(candidate, c.distance_scale)
        return c.exploration_weight * worth / (worth + c.exploration_half)

    def _propose(self, goal: str, view: View, failed: Sequence[str]) -> str:
        tried = {normalize_phrase(phrase) for phrase in failed}
        fresh = [label for label, _ in self.visible(view.semantic) if normalize_phrase(label) not in tried]
        scored = [(self.relatedness(label, goal), label) for label in fresh]
        good = [(r, label) for r, label in scored if r >= self.config.uncertain_similarity]
        if good:
            return max(good, key=lambda item: item[0])[1]  # max keeps the first (largest) of equals
        return next((p for p in goal_phrases(goal, self._truth) if normalize_phrase(p) not in tried), goal)

    def _hints(self, goal: str) -> CategoryHints:
        vocabulary = self._truth.vocabulary if self._truth is not None else None
        if vocabulary is None:
            return CategoryHints.unknown()
        own = category_key(goal, self._truth)
        name = normalize_phrase(own)
        others = [c for c in vocabulary.categories() if category_key(c, self._truth) != own]
        nearest = _nearest(name, others, self.embedder)
        closest = nearest[0][0] if nearest else self.config.unrelated_similarity
        low, high = HINT_THRESHOLDS
        threshold = round(low + (high - low) * _ramp(closest, self.config), 2)
        rooms = _nearest(name, list(vocabulary.room_types), self.embedder)
        room = rooms[0][1] if rooms and rooms[0][0] >= self.config.room_similarity else EVERYWHERE
        similar = tuple(c for _, c in nearest[: self.config.similar_objects])
        return CategoryHints(similar, threshold, room)

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        """Where the goal is usually found (the vocabulary's room shares: common knowledge of homes) against the
        rooms the views show (a visible category found mostly, ``room_evidence`` of its share, in one room type
        shows that room): ``this`` where the rooms shown hold ``floor_this`` of the goal's share, ``other`` where
        at least ``floor_rooms`` rooms are shown, ``floor_passages`` (hallways) not counted, and they hold at most
        ``floor_other`` of it (a ground floor of kitchen and living room for a bed), else ``unsure``. For ``other``
        the rooms shown are completed with what every home is known to have (:meth:`_held`): a bathroom on every
        floor (``floor_everywhere``), and the entrance floor's rooms kept together (``floor_together``), so that a
        kitchen not yet seen beside a living room is no reason for ``other``; the ``this`` share stays what the
        views show. It reads only what the views show."""
        return self._timed(FLOOR_KIND, lambda: self._floor(goal, views))

    def _floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        vocabulary = self._truth.vocabulary if self._truth is not None else None
        if vocabulary is None:
            return FloorJudgement("unsure", note="no vocabulary")
        wanted = vocabulary.room_shares(category_key(goal, self._truth))
        if not wanted:
            return FloorJudgement("unsure", note="rooms of the goal unknown")
        seen = {label for view in views for label, _ in self.visible(view.semantic)}
        here = {room for label in seen if (room := self._room_of(vocabulary, label)) is not None}
        share = sum(wanted.get(room, 0.0) for room in here)
        note = f"{share:.2f} of the goal's rooms among {', '.join(sorted(here)) or 'none'}"
        if share >= self.config.floor_this:
            return FloorJudgement("this", note=note)
        held = self._held(here)
        possible = sum(wanted.get(room, 0.0) for room in held)
        if possible > share:
            note += f"; {possible:.2f} with the rooms this floor has unseen"
        telling = here - set(self.config.floor_passages)  # every floor has its hallways: they tell no floor apart
        if len(telling) >= self.config.floor_rooms and possible <= self.config.floor_other:
            return FloorJudgement("other", note=note)
        return FloorJudgement("unsure", note=note)

    def _held(self, shown: set[str]) -> set[str]:
        """The rooms a floor showing ``shown`` has (common knowledge of homes): those, the rooms every floor has
        (``floor_everywhere``), and the entrance floor's rooms (``floor_together``) where it shows one of them."""
        together = set(self.config.floor_together)
        return shown | set(self.config.floor_everywhere) | (together if shown & together else set())

    def _room_of(self, vocabulary: CategoryVocabulary, category: str) -> str | None:
        """The room a category shows: the one holding at least ``room_evidence`` of its objects, if any."""
        shares = vocabulary.room_shares(category)
        room, share = max(shares.items(), key=lambda item: item[1], default=("", 0.0))
        return room if share >= self.config.room_evidence else None

    def _judge(self, goal: str, frame: VerificationFrame) -> Judgement:
        if frame.semantic is None:
            return "uncertain"
        label = label_under_mask(frame.semantic, frame.mask, self._labels)
        if label is None:
            return "not"
        related = self.relatedness(label, goal)
        if related >= self.config.sure_similarity:
            return "sure"
        return "uncertain" if related >= self.config.uncertain_similarity else "not"


def _nearest(name: str, texts: Sequence[str], embedder: TextEmbedder) -> list[tuple[float, str]]:
    """``texts`` with their embedding cosine to ``name``, nearest first (ties by text)."""
    scored = [(embedder.similarity(name, normalize_phrase(text)), text) for text in texts]
    return sorted(scored, key=lambda item: (-item[0], item[1]))


def goal_phrases(goal: str, truth: GroundTruth | None) -> list[str]:
    """The goal's category name and its synonyms in the world's vocabulary (just the goal text outside it)."""
    vocabulary = truth.vocabulary if truth is not None else None
    category = vocabulary.canonical(goal) if vocabulary is not None else None
    names = [category, *vocabulary.synonyms(category)] if vocabulary is not None and category is not None else [goal]
    return list(dict.fromkeys(names))
