"""SAM3 as the grounder: promptable concept segmentation of a noun phrase (paper Sec. IV-B, V-A).

DRIVE-Nav uses SAM3 directly as its open-vocabulary detector: every step it segments the target category (or an
enriched phrase) in the RGB frame and returns one instance mask per match. Through transformers this is
``Sam3Processor`` (image + text prompt) -> ``Sam3Model`` -> ``post_process_instance_segmentation``, whose score is
the query's probability times the image-level presence probability. The released processor's image half is
torchvision's only (the fast image processor, which runs on the model's device). The paper measures about 270 ms
per SAM3 call on its RTX 4090 deployment machine (Sec. V-E).

The forward is split as ``Sam3Model`` allows: ``get_text_features`` once per phrase and episode,
``get_vision_features`` once per frame, then the forward on both (``text_embeds`` / ``vision_embeds``), which runs
the same layers on the same tensors as the plain forward. ``models.compile`` compiles the vision encoder and that
forward (the DETR encoder and decoder and the mask decoder).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.semantics.hf_common import (
    TransformersGrounder,
    load_fast_processor,
    load_pair,
    ranked_detections,
)
from drivenav.semantics.protocols import Detection

SAM3_EXPECTED = "a local SAM3 checkpoint directory or a model id in the Hugging Face cache"


@dataclass(frozen=True)
class Sam3Text:
    """One phrase's text encoder output (``Sam3Model.get_text_features``) and its attention mask (batch of one)."""

    features: Any
    attention_mask: Any


class Sam3Grounder(TransformersGrounder):
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with a transformers SAM3 checkpoint.

    ``model`` is a checkpoint directory or a cached model id (never downloaded). Instances scoring strictly above
    ``score_threshold`` are kept; mask probabilities above ``mask_threshold`` form the mask, resized to the frame.
    ``dtype`` is ``models.dtype`` (``auto``, ``float32``, ``bfloat16``, ``float16``), ``compile_backend``
    ``models.compile``'s (:func:`~drivenav.semantics.hf_common.compile_backend_for`). ``model_obj`` /
    ``processor_obj`` inject already-built objects (tests, shared GPU copies) instead of loading.
    """

    name = "sam3"

    def __init__(
        self,
        model: str | Path = "facebook/sam3",
        device: str | None = None,
        score_threshold: float = 0.5,
        mask_threshold: float = 0.5,
        *,
        dtype: str = "auto",
        compile_backend: str = "",
        model_obj: Any = None,
        processor_obj: Any = None,
    ) -> None:
        from transformers import Sam3Model, Sam3Processor

        fast_processor = load_fast_processor(Sam3Processor.from_pretrained)
        loaded, processor = load_pair(
            Sam3Model.from_pretrained, fast_processor, model, SAM3_EXPECTED, model_obj, processor_obj
        )
        super().__init__(loaded, processor, device, dtype, compile_backend)
        self.score_threshold = score_threshold
        self.mask_threshold = mask_threshold

    def compiled_modules(self) -> list[Any]:
        return [self.model.vision_encoder, self.model]

    def encode_text(self, text: str) -> Sam3Text:
        input_ids, attention_mask = self.tokens(text)
        return Sam3Text(
            self.model.get_text_features(input_ids=input_ids, attention_mask=attention_mask), attention_mask
        )

    def encode_vision(self, pixels: Any) -> Any:
        return self.model.get_vision_features(pixel_values=pixels)

    def decode_rows(self, vision: Any, texts: Sequence[Sam3Text]) -> Any:
        """The forward on each row's vision features and its own phrase's text features (the forward reads only
        the pooled output)."""
        import torch
        from transformers.modeling_outputs import BaseModelOutputWithPooling

        if len(texts) == 1:
            features, mask = texts[0].features, texts[0].attention_mask
        else:
            pooled = torch.cat([text.features.pooler_output for text in texts])
            features = BaseModelOutputWithPooling(pooler_output=pooled)
            mask = torch.cat([text.attention_mask for text in texts])
        return self.model(vision_embeds=vision, text_embeds=features, attention_mask=mask)

    def postprocess(
        self, outputs: Any, frames: Sequence[NDArray[np.uint8]], phrases: Sequence[str]
    ) -> list[list[Detection]]:
        """The detections of each row, labelled with its phrase."""
        results = self.processor.post_process_instance_segmentation(
            outputs,
            threshold=self.score_threshold,
            mask_threshold=self.mask_threshold,
            target_sizes=[frame.shape[:2] for frame in frames],
        )
        return [
            ranked_detections(result["scores"].float().cpu().numpy(), result["masks"].bool().cpu().numpy(), label)
            for result, label in zip(results, phrases, strict=True)
        ]
