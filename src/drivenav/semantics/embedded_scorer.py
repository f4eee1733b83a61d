"""The embedded world's image-text scorer: BLIP-2 ITM's role in the VLFM baseline (Yokoyama et al., ICRA 2024),
answered from what the frame shows.

VLFM scores every RGB frame by BLIP-2's image-text cosine with "Seems like there is a {target} ahead." and spreads
that score over its value map. In the embedded world this stand-in scores a frame with exactly the knowledge of
the embedded reasoner (:mod:`drivenav.semantics.embedded`), so that VLFM and DRIVE-Nav are compared on equal terms:
the frame's visible labels (read from its ``semantic`` instance image through the episode's ground truth, at least
``min_pixels`` pixels a label) and their relatedness to the goal (1 for the goal's own category, else the cosine of
all-MiniLM-L6-v2 sentence embeddings). The score is the reasoner's ``semantic`` term of a view
(:func:`~drivenav.semantics.embedded.semantic_value`): the max over the visible labels of
``ramp(relatedness) * area_weight(share)``, in [0, 1). At a given area the goal itself scores highest, and a view
of the goal is never below ``area_floor``; a frame of unrelated things scores 0.

Without a ``semantic`` image nothing is recognisable, so the score is the neutral 0 of a frame with no visible
label: no evidence for or against any part of the map.

A method's own text that names a room as well as the target (ApexNav's "Seems like there is a {room} or a
{target} ahead?", :class:`~drivenav.semantics.protocols.ScorePrompt`) matches a frame that shows either: a label's
relatedness is then the larger of its relatedness to the goal and its embedding cosine with the room ("stove" is
near "kitchen"), so a room's furniture raises the score where the target is not in view. The template's other
words play no part, as they play none for VLFM's text.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from drivenav.semantics.embedded import (
    EmbeddedReasonerConfig,
    label_areas,
    normalize_phrase,
    relatedness,
    semantic_value,
)
from drivenav.semantics.embedding import TextEmbedder, default_embedder
from drivenav.semantics.protocols import ModelCall, ScorePrompt
from drivenav.types import GroundTruth, Observation


class EmbeddedScorer:
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` from the frame's instance labels (module
    docstring); ``config`` is the embedded reasoner's, so both stand-ins read a frame alike."""

    name = "embedded"

    def __init__(self, embedder: TextEmbedder | None = None, config: EmbeddedReasonerConfig | None = None) -> None:
        self._embedder = embedder
        self.config = config or EmbeddedReasonerConfig()
        self.calls: list[ModelCall] = []
        self._truth: GroundTruth | None = None
        self._labels: dict[int, str] = {}

    @property
    def embedder(self) -> TextEmbedder:
        """The embedding model (the shared default, loaded on first use, unless one was given)."""
        if self._embedder is None:
            self._embedder = default_embedder()
        return self._embedder

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.calls = []
        self._truth = truth
        self._labels = dict(truth.labels or {}) if truth is not None else {}

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        """The frame's semantic value for ``goal`` (and ``prompt``'s room, if it names one) in [0, 1) (0 without
        an instance image); the RGB image is not read (nor rendered, where the world defers it)."""
        start = time.perf_counter()
        semantic = observation.semantic
        room = prompt.room if prompt is not None and "{room}" in prompt.template else ""
        value = 0.0 if semantic is None else self._value(goal, room, semantic)
        self.calls.append(ModelCall("score", (time.perf_counter() - start) * 1000.0, "ok"))
        return value

    def _value(self, goal: str, room: str, semantic: NDArray[np.int32]) -> float:
        shown = label_areas(semantic, self._labels, self.config.min_pixels)
        pixels = semantic.size
        related = [(self._related(label, goal, room), area / pixels) for label, area in shown]
        return semantic_value(related, self.config)

    def _related(self, label: str, goal: str, room: str) -> float:
        """The label's relatedness to the goal, or to the room where the text names one and that is nearer."""
        to_goal = relatedness(label, goal, self._truth, self.embedder)
        if not room:
            return to_goal
        return max(to_goal, self.embedder.similarity(normalize_phrase(label), normalize_phrase(room)))
