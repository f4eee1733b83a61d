"""What a model returns, checked at the protocol boundary (issue 60): the same checks in process and served.

Every grounder and image-text scorer an agent uses is built wrapped (:class:`CheckedGrounder`,
:class:`CheckedScorer`; :mod:`drivenav.semantics.registry`), and a grounder server wraps the grounder it serves,
so a plug-in model, a real model in half precision and a served one answer the agent alike:

- a similarity that is not a finite number within :data:`SIMILARITY_BOUND` of 0 (the scale of every scorer,
  :class:`~drivenav.semantics.protocols.ImageTextScorer`) is a ``fallback`` call answering 0;
- a detection whose score is not a number in [0, 1], or whose mask is not the frame's size, is dropped;
- an integer mask (0 and 1, or any nonzero value) is turned into a boolean one, once, as it is read: the agent
  indexes images with masks, and an integer array indexes by position (slow, and wrong);
- at most ``models.max_detections`` detections a frame are kept (a server's ``max_detections``), the best
  scores, in the model's order: each one costs the agent a pass over the frame.

Each kind of fault is logged as a warning the first time a model makes it, and at debug level afterwards (a
scorer gone bad answers every frame). The built-in models never make one, so their episodes are unchanged.
"""

from __future__ import annotations

import logging
import numbers
import time
from collections.abc import Sequence
from typing import Final

import numpy as np

from drivenav.semantics.protocols import Detection, Grounder, ImageTextScorer, ModelCall, ScorePrompt, prefetch
from drivenav.semantics.serve_config import DEFAULT_MAX_DETECTIONS
from drivenav.semantics.wrapped import Wrapped
from drivenav.types import GroundTruth, Observation

log = logging.getLogger(__name__)

SIMILARITY_BOUND: Final[float] = 1.0 + 1e-3
"""The largest similarity's size: every scorer's similarity lies in [-1, 1] (a cosine, a probability), with room
for a float32 cosine's rounding past 1."""


def usable_similarity(value: object) -> float | None:
    """``value`` as a similarity (a real number within :data:`SIMILARITY_BOUND` of 0), else None."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    similarity = float(value)
    return similarity if abs(similarity) <= SIMILARITY_BOUND else None  # NaN compares false


def usable_score(value: object) -> float | None:
    """``value`` as a detection's confidence (a real number in [0, 1]), else None."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    score = float(value)
    return score if 0.0 <= score <= 1.0 else None  # NaN compares false


class _Faults:
    """A model's faults by kind: the first of each kind a warning naming the model, the others at debug level."""

    def __init__(self, model: str) -> None:
        self.model = model
        self.seen: set[str] = set()

    def report(self, kind: str, detail: str) -> None:
        level = logging.DEBUG if kind in self.seen else logging.WARNING
        self.seen.add(kind)
        log.log(level, "model %s: %s (%s)", self.model, kind, detail)


class CheckedScorer(Wrapped[ImageTextScorer]):
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` with ``inner``, each similarity checked
    (module docstring): one that is not usable answers 0 and marks its call a ``fallback``."""

    def __init__(self, inner: ImageTextScorer) -> None:
        super().__init__(inner)
        self._faults = _Faults(f"{inner.name} (scorer)")

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.inner.begin_episode(truth)

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        start, made = time.perf_counter(), len(self.inner.calls)
        value = self.inner.score(goal, observation, prompt)
        similarity = usable_similarity(value)
        if similarity is not None:
            return similarity
        self._faults.report("a similarity not within [-1, 1] answered 0", repr(value))
        latency = self.inner.calls[-1].latency_ms if len(self.inner.calls) > made else None
        del self.inner.calls[made:]
        self.inner.calls.append(ModelCall("score", latency or (time.perf_counter() - start) * 1000.0, "fallback"))
        return 0.0


class DetectionCheck:
    """The checks of a grounder's detections (module docstring), at most ``max_detections`` a frame kept; ``model``
    names the grounder in the log."""

    def __init__(self, model: str, max_detections: int = DEFAULT_MAX_DETECTIONS) -> None:
        self.max_detections = max_detections
        self._faults = _Faults(model)

    def checked(self, found: Sequence[object], size: tuple[int, ...]) -> list[Detection]:
        """The usable detections of ``found`` on a frame of ``size`` (height, width): the best
        ``max_detections`` of them, in the model's order."""
        scored = [pair for item in found if (pair := self._scored(item)) is not None]
        kept = self._best(scored)
        return [checked for detection in kept if (checked := self._mask(detection, size)) is not None]

    def _scored(self, item: object) -> tuple[Detection, float] | None:
        """The detection and its score, or None (logged) when it is not a detection with a score in [0, 1]."""
        if not isinstance(item, Detection):
            self._faults.report("an answer that is not a Detection dropped", type(item).__name__)
            return None
        score = usable_score(item.score)
        if score is None:
            self._faults.report("a detection with a score not in [0, 1] dropped", repr(item.score))
            return None
        return item, score

    def _best(self, scored: list[tuple[Detection, float]]) -> list[Detection]:
        """The ``max_detections`` best-scored detections (the first of equal ones), in the model's order."""
        if len(scored) <= self.max_detections:
            return [detection for detection, _ in scored]
        self._faults.report(f"more than {self.max_detections} detections a frame cut", f"{len(scored)}")
        best = sorted(range(len(scored)), key=lambda i: -scored[i][1])[: self.max_detections]
        return [scored[i][0] for i in sorted(best)]

    def _mask(self, detection: Detection, size: tuple[int, ...]) -> Detection | None:
        """The detection with a boolean mask of the frame's ``size`` (an integer one converted), else None."""
        mask: object = detection.mask
        if not isinstance(mask, np.ndarray) or mask.shape != size:
            shape = getattr(mask, "shape", type(mask).__name__)
            self._faults.report(f"a detection whose mask is not the frame's {size} dropped", f"{shape}")
            return None
        if mask.dtype == np.bool_:
            return detection
        if not np.issubdtype(mask.dtype, np.integer):
            self._faults.report("a detection whose mask is neither boolean nor integer dropped", str(mask.dtype))
            return None
        return Detection(mask != 0, detection.score, detection.phrase)


class CheckedGrounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with ``inner``, each frame's detections checked
    (:class:`DetectionCheck`, at most ``max_detections`` kept)."""

    def __init__(self, inner: Grounder, max_detections: int = DEFAULT_MAX_DETECTIONS) -> None:
        self.inner = inner
        self.name = inner.name
        self.check = DetectionCheck(f"{inner.name} (grounder)", max_detections)

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        self.inner.begin_episode(truth, seed)

    def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None:
        prefetch(self.inner, observation, phrases)

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        return self.check.checked(self.inner.segment(observation, phrase), observation.depth.shape[:2])
