"""OWLv2 boxes turned into masks: the grounding backbone DRIVE-Nav is compared against (paper Sec. V-D).

The paper's comparison pairs OWLv2 (text-conditioned open-vocabulary boxes) with MobileSAM (box-prompted masks),
as VLFM does. Through transformers: ``Owlv2Processor`` (image + one text query) -> ``Owlv2ForObjectDetection``
-> ``post_process_grounded_object_detection`` gives scored boxes in frame pixels (the processor pads the frame to
a square, so boxes may reach past its bottom or right edge); a :class:`BoxSegmenter` then turns each box into a
mask. MobileSAM is not packaged here, so the default segmenter is :class:`FilledBoxSegmenter`: the box itself
filled, which over-covers the object but keeps the object's position and extent.

The forward is split as the model's own parts allow: the text query embedding (``Owlv2Model.get_text_features``,
projected and L2-normalised as the plain forward does) once per phrase and episode; the image embedding
(``image_embedder``) and the text-independent boxes (``box_predictor``) once per frame; then the class head on both.
Only the :data:`OWLV2_MAX_BOXES` best boxes above the threshold are turned into masks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.semantics.hf_common import TransformersGrounder, load_fast_processor, load_pair, ranked_detections
from drivenav.semantics.protocols import Detection

OWLV2_EXPECTED = "a local OWLv2 checkpoint directory or a model id in the Hugging Face cache"

OWLV2_MAX_BOXES: Final[int] = 100
"""Boxes kept per frame, best scores first, before masks are made (ours; the 100 detections per image of COCO's
detection evaluation). OWLv2 base/16 scores 3,600 patch boxes; at a low threshold thousands pass, and filling one
mask per box cost about 240 ms a frame (issue 37)."""


class BoxSegmenter(Protocol):
    """Box-prompted segmentation (MobileSAM's role in Sec. V-D).

    ``boxes`` is ``(N, 4)`` pixel corners ``(x0, y0, x1, y1)``, possibly reaching past the frame; the answer is
    ``(N, H, W)`` bool masks over the ``(H, W, 3)`` frame, one per box.
    """

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]: ...


class FilledBoxSegmenter:
    """The fallback :class:`BoxSegmenter`: a pixel belongs to a box's mask when its centre lies inside the box."""

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
        height, width = rgb.shape[:2]
        rows = np.arange(height) + 0.5
        cols = np.arange(width) + 0.5
        x0, y0, x1, y1 = (boxes[:, k, None] for k in range(4))
        inside_rows = (rows >= y0) & (rows < y1)
        inside_cols = (cols >= x0) & (cols < x1)
        masks: NDArray[np.bool_] = inside_rows[:, :, None] & inside_cols[:, None, :]
        return masks


@dataclass(frozen=True)
class Owlv2Text:
    """One phrase's query embedding, ``(1, 1, D)`` and L2-normalised, and its query mask ``(1, 1)`` (a query whose
    first token is the pad id is masked out, as in the plain forward)."""

    embeds: Any
    query_mask: Any


@dataclass(frozen=True)
class Owlv2Vision:
    """A batch of frames' patch features ``(B, P, D)`` and their boxes ``(B, P, 4)`` (centre, size; 0..1)."""

    image_feats: Any
    boxes: Any


class Owlv2Grounder(TransformersGrounder):
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with an OWLv2 checkpoint and a box segmenter.

    ``model`` is a checkpoint directory or a cached model id (never downloaded); its processor is loaded with
    torchvision's image processor only (the PIL one costs about 300 ms a frame; without torchvision loading fails).
    Boxes scoring strictly above ``score_threshold`` are kept (0.1 is the transformers default for OWLv2), at most
    ``max_boxes`` of them, best first. ``dtype`` is ``models.dtype``. ``model_obj`` / ``processor_obj`` inject
    already-built objects instead of loading; ``segmenter`` defaults to :class:`FilledBoxSegmenter`.
    """

    name = "owlv2"

    def __init__(
        self,
        model: str | Path = "google/owlv2-base-patch16-ensemble",
        device: str | None = None,
        score_threshold: float = 0.1,
        *,
        max_boxes: int = OWLV2_MAX_BOXES,
        dtype: str = "auto",
        model_obj: Any = None,
        processor_obj: Any = None,
        segmenter: BoxSegmenter | None = None,
    ) -> None:
        from transformers import Owlv2ForObjectDetection, Owlv2Processor

        loaded, processor = load_pair(
            Owlv2ForObjectDetection.from_pretrained,
            load_fast_processor(Owlv2Processor.from_pretrained),
            model,
            OWLV2_EXPECTED,
            model_obj,
            processor_obj,
        )
        super().__init__(loaded, processor, device, dtype)
        self.score_threshold = score_threshold
        self.max_boxes = max_boxes
        self.segmenter: BoxSegmenter = segmenter if segmenter is not None else FilledBoxSegmenter()

    def encode_text(self, text: str) -> Owlv2Text:
        import torch

        input_ids, attention_mask = self.tokens(text)
        embeds = self.model.owlv2.get_text_features(input_ids=input_ids, attention_mask=attention_mask).pooler_output
        embeds = embeds / torch.linalg.norm(embeds, ord=2, dim=-1, keepdim=True)
        return Owlv2Text(embeds[None], input_ids[None, :, 0] > 0)

    def encode_vision(self, pixels: Any) -> Owlv2Vision:
        feature_map = self.model.image_embedder(pixel_values=pixels)[0]
        batch, rows, cols, width = feature_map.shape
        image_feats = feature_map.reshape(batch, rows * cols, width)
        return Owlv2Vision(image_feats, self.model.box_predictor(image_feats, feature_map))

    def decode(self, vision: Owlv2Vision, text: Owlv2Text) -> Any:
        from transformers.models.owlv2.modeling_owlv2 import Owlv2ObjectDetectionOutput

        batch = vision.image_feats.shape[0]
        logits = self.model.class_predictor(
            vision.image_feats, text.embeds.expand(batch, -1, -1), text.query_mask.expand(batch, -1)
        )[0]
        return Owlv2ObjectDetectionOutput(logits=logits, pred_boxes=vision.boxes)

    def postprocess(self, outputs: Any, frames: Sequence[NDArray[np.uint8]], phrase: str) -> list[list[Detection]]:
        results = self.processor.post_process_grounded_object_detection(
            outputs, threshold=self.score_threshold, target_sizes=[frame.shape[:2] for frame in frames]
        )
        return [self._detections(result, frame, phrase) for result, frame in zip(results, frames, strict=True)]

    def _detections(self, result: dict[str, Any], rgb: NDArray[np.uint8], phrase: str) -> list[Detection]:
        """The ``max_boxes`` best boxes of one frame as masks, then as detections (the segmenter sees no others)."""
        height, width = rgb.shape[:2]
        scores = result["scores"].float().cpu().numpy()
        best = np.argsort(-scores, kind="stable")[: self.max_boxes]
        scores = scores[best]
        boxes = result["boxes"].float().cpu().numpy()[best]
        masks = self.segmenter.segment_boxes(rgb, boxes)
        if masks.shape != (len(boxes), height, width):
            raise ValueError(
                f"box segmenter returned masks of shape {masks.shape}, expected {(len(boxes), height, width)}"
            )
        return ranked_detections(scores, masks, phrase)
