"""OWLv2 boxes turned into masks: the grounding backbone DRIVE-Nav is compared against (paper Sec. V-D).

The paper's comparison pairs OWLv2 (text-conditioned open-vocabulary boxes) with MobileSAM (box-prompted masks),
as VLFM does. Through transformers: ``Owlv2Processor`` (image + one text query) -> ``Owlv2ForObjectDetection``
-> ``post_process_grounded_object_detection`` gives scored boxes in frame pixels (the processor pads the frame to
a square, so boxes may reach past its bottom or right edge); a box segmenter (:mod:`drivenav.semantics.boxes`:
the filled box, or MobileSAM with ``--segmenter mobilesam``) then turns each box into a mask.

The forward is split as the model's own parts allow: the text query embedding (``Owlv2Model.get_text_features``,
projected and L2-normalised as the plain forward does) once per phrase and episode; the image embedding
(``image_embedder``) and the text-independent boxes (``box_predictor``) once per frame; then the class head on both.
Only the :data:`~drivenav.semantics.boxes.MAX_BOXES` best boxes above the threshold are turned into masks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.semantics.boxes import MAX_BOXES, BoxGrounder, BoxSegmenter
from drivenav.semantics.hf_common import load_fast_processor, load_pair

OWLV2_EXPECTED = "a local OWLv2 checkpoint directory or a model id in the Hugging Face cache"


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


class Owlv2Grounder(BoxGrounder):
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with an OWLv2 checkpoint and a box segmenter.

    ``model`` is a checkpoint directory or a cached model id (never downloaded); its processor is loaded with
    torchvision's image processor only (the PIL one costs about 300 ms a frame; without torchvision loading fails).
    Boxes scoring strictly above ``score_threshold`` are kept (0.1 is the transformers default for OWLv2), at most
    ``max_boxes`` of them, best first. ``dtype`` is ``models.dtype``, ``compile_backend`` ``models.compile``'s
    (:func:`~drivenav.semantics.hf_common.compile_backend_for`). ``model_obj`` / ``processor_obj`` inject
    already-built objects instead of loading; ``segmenter`` defaults to the filled box.
    """

    name = "owlv2"

    def __init__(
        self,
        model: str | Path = "google/owlv2-base-patch16-ensemble",
        device: str | None = None,
        score_threshold: float = 0.1,
        *,
        max_boxes: int = MAX_BOXES,
        dtype: str = "auto",
        compile_backend: str = "",
        model_obj: Any = None,
        processor_obj: Any = None,
        segmenter: BoxSegmenter | None = None,
    ) -> None:
        from transformers import Owlv2ForObjectDetection, Owlv2Processor

        loaders = Owlv2ForObjectDetection.from_pretrained, load_fast_processor(Owlv2Processor.from_pretrained)
        pair = load_pair(*loaders, model, OWLV2_EXPECTED, model_obj, processor_obj)
        super().__init__(*pair, device, dtype, score_threshold, max_boxes, segmenter, compile_backend)

    def compiled_modules(self) -> list[Any]:
        return [self.model.owlv2.vision_model, self.model.box_head, self.model.class_head]

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

    def decode_rows(self, vision: Owlv2Vision, texts: Sequence[Owlv2Text]) -> Any:
        """The class head on each row's patch features and its own phrase's query embedding."""
        import torch
        from transformers.models.owlv2.modeling_owlv2 import Owlv2ObjectDetectionOutput

        embeds = torch.cat([text.embeds for text in texts])
        query_mask = torch.cat([text.query_mask for text in texts])
        logits = self.model.class_predictor(vision.image_feats, embeds, query_mask)[0]
        return Owlv2ObjectDetectionOutput(logits=logits, pred_boxes=vision.boxes)

    def scored_boxes(self, outputs: Any, frames: Sequence[NDArray[np.uint8]]) -> list[tuple[Any, Any]]:
        results = self.processor.post_process_grounded_object_detection(
            outputs, threshold=self.score_threshold, target_sizes=[frame.shape[:2] for frame in frames]
        )
        return [(result["scores"], result["boxes"]) for result in results]
