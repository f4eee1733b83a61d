"""The embedded world's ground-truth grounder: perfect segmentation from the instance image (SAM3's role, Sec. IV-B).

A phrase and every instance label are resolved to a category with the world's vocabulary (ground truth, see
:func:`~drivenav.semantics.protocols.category_key`; names outside it fall back to their lower-cased, stripped
text), so a synonym such as "couch" grounds the sofa instances. Each visible instance of the category
with at least ``min_pixels`` pixels becomes one :class:`~drivenav.semantics.protocols.Detection` of score 1.
The default of 150 pixels is about 0.05% of a 640x480 frame, e.g. a 12x12 pixel blob: a 0.3 m wide object
about 4 m away under the 79 degree field of view; smaller glimpses are left to closer views, as a real
segmenter would miss them.
"""

from __future__ import annotations

import numpy as np

from drivenav.semantics.protocols import Detection, category_key
from drivenav.types import GroundTruth, Observation


class GroundTruthGrounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` from ``Observation.semantic``."""

    name = "ground-truth"

    def __init__(self, truth: GroundTruth | None = None, min_pixels: int = 150) -> None:
        if min_pixels < 1:
            raise ValueError(f"min_pixels must be >= 1, got {min_pixels}")
        self.min_pixels = min_pixels
        self.begin_episode(truth, 0)

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Learn what this episode's instance ids mean (``seed`` is unused: the detector is exact)."""
        self._truth = truth
        labels = truth.labels if truth is not None and truth.labels is not None else {}
        self._categories = {i: category_key(label, truth) for i, label in labels.items()}

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        """One detection per visible instance of ``phrase``'s category, largest mask first ([] without semantics)."""
        semantic = observation.semantic
        if semantic is None:
            return []
        target = category_key(phrase, self._truth)
        ids = sorted(i for i, category in self._categories.items() if i != 0 and category == target)
        masks = [semantic == i for i in ids]
        sized = [(int(np.count_nonzero(mask)), mask) for mask in masks]
        sized.sort(key=lambda item: -item[0])  # stable: equal sizes keep instance-id order
        return [Detection(mask, 1.0, phrase) for count, mask in sized if count >= self.min_pixels]
