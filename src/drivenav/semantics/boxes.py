"""Box detectors turned into grounders: scored boxes, then one mask per box from a box segmenter (paper Sec. V-D).

The paper's grounding comparison pairs OWLv2 with MobileSAM, as VLFM and ApexNav pair their detectors (Grounding
DINO, YOLO) with it. :class:`BoxGrounder` is what OWLv2 and Grounding DINO share: the detector's boxes scoring
strictly above the threshold, at most :data:`MAX_BOXES` of them (best first), become masks through a
:class:`BoxSegmenter`, the box filled (:class:`FilledBoxSegmenter`, no model) or MobileSAM's mask
(:mod:`drivenav.semantics.mobilesam_segmenter`).

A pixel is inside a box when its centre is: pixel ``(row, col)`` has its centre at ``(col + 0.5, row + 0.5)`` in
the box's pixel coordinates (:func:`box_pixel_ranges`).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import Any, Final, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.semantics.hf_common import TransformersGrounder, ranked_detections
from drivenav.semantics.protocols import Detection

MAX_BOXES: Final[int] = 100
"""Boxes kept per frame, best scores first, before masks are made (ours; the 100 detections per image of COCO's
detection evaluation). OWLv2 base/16 scores 3,600 patch boxes and Grounding DINO 900 queries; at a low threshold
thousands pass, and filling one mask per box cost about 240 ms a frame (issue 37)."""


class BoxSegmenter(Protocol):
    """Box-prompted segmentation (MobileSAM's role in Sec. V-D).

    ``boxes`` is ``(N, 4)`` pixel corners ``(x0, y0, x1, y1)``, possibly reaching past the frame; the answer is
    ``(N, H, W)`` bool masks over the ``(H, W, 3)`` frame, one per box, each inside its box.
    """

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]: ...


def box_pixel_ranges(boxes: NDArray[np.float32], height: int, width: int) -> NDArray[np.int64]:
    """Each box's pixels as ``(N, 4)`` half-open ranges ``(row0, row1, col0, col1)`` inside an ``height`` x
    ``width`` frame: the rows and columns whose pixel centres lie in ``[y0, y1)`` and ``[x0, x1)`` (an empty range
    has ``row1 <= row0`` or ``col1 <= col0``)."""
    x0, y0, x1, y1 = (np.asarray(boxes, dtype=np.float64)[:, k] for k in range(4))
    rows = np.clip(np.ceil(np.stack([y0, y1], axis=1) - 0.5), 0, height)
    cols = np.clip(np.ceil(np.stack([x0, x1], axis=1) - 0.5), 0, width)
    return np.concatenate([rows, cols], axis=1).astype(np.int64)


class FilledBoxSegmenter:
    """The :class:`BoxSegmenter` without a model: a pixel belongs to a box's mask when its centre lies inside the
    box (the mask over-covers the object but keeps its position and extent)."""

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
        height, width = rgb.shape[:2]
        masks = np.zeros((len(boxes), height, width), dtype=bool)
        for mask, (row0, row1, col0, col1) in zip(masks, box_pixel_ranges(boxes, height, width), strict=True):
            mask[row0:row1, col0:col1] = True
        return masks


def inside_boxes(masks: NDArray[np.bool_], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
    """``masks`` (``(N, H, W)``, one per box) with every pixel outside its box cleared."""
    height, width = masks.shape[1:]
    kept = np.zeros_like(masks)
    for k, (row0, row1, col0, col1) in enumerate(box_pixel_ranges(boxes, height, width)):
        kept[k, row0:row1, col0:col1] = masks[k, row0:row1, col0:col1]
    return kept


class BoxGrounder(TransformersGrounder):
    """A :class:`~drivenav.semantics.hf_common.TransformersGrounder` whose model gives scored boxes (OWLv2,
    Grounding DINO): :meth:`scored_boxes` reads them from the raw output, and the ``max_boxes`` best scoring
    strictly above ``score_threshold`` become masks through ``segmenter`` (default :class:`FilledBoxSegmenter`),
    which sees no other box."""

    def __init__(
        self,
        model: Any,
        processor: Any,
        device: str | None,
        dtype: str,
        score_threshold: float,
        max_boxes: int,
        segmenter: BoxSegmenter | None,
        compile_backend: str,
    ) -> None:
        super().__init__(model, processor, device, dtype, compile_backend)
        self.score_threshold = score_threshold
        self.max_boxes = max_boxes
        self.segmenter: BoxSegmenter = segmenter if segmenter is not None else FilledBoxSegmenter()

    @abstractmethod
    def scored_boxes(self, outputs: Any, frames: Sequence[NDArray[np.uint8]]) -> list[tuple[Any, Any]]:
        """Per frame, the scores ``(K,)`` and pixel corners ``(K, 4)`` (tensors) of the boxes scoring strictly above
        ``score_threshold``."""

    def postprocess(
        self, outputs: Any, frames: Sequence[NDArray[np.uint8]], phrases: Sequence[str]
    ) -> list[list[Detection]]:
        found = self.scored_boxes(outputs, frames)
        rows = zip(found, frames, phrases, strict=True)
        return [self.box_detections(scores, boxes, frame, phrase) for (scores, boxes), frame, phrase in rows]

    def box_detections(self, scores: Any, boxes: Any, rgb: NDArray[np.uint8], phrase: str) -> list[Detection]:
        """The ``max_boxes`` best boxes of one frame as masks, then as detections."""
        height, width = rgb.shape[:2]
        values = scores.float().cpu().numpy()
        best = np.argsort(-values, kind="stable")[: self.max_boxes]
        corners = boxes.float().cpu().numpy()[best]
        masks = self.segmenter.segment_boxes(rgb, corners)
        if masks.shape != (len(corners), height, width):
            raise ValueError(
                f"box segmenter returned masks of shape {masks.shape}, expected {(len(corners), height, width)}"
            )
        return ranked_detections(values[best], masks, phrase)
