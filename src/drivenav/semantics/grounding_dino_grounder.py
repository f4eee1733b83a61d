"""Grounding DINO boxes turned into masks: the detector of VLFM and ApexNav, the paper's peers (Sec. V-D).

Grounding DINO (Liu et al., ECCV 2024) grounds a text in an image with a Swin backbone, a BERT text encoder, an
encoder that fuses the image and text features, and a DETR decoder whose queries are scored against each text
token. Through transformers: ``GroundingDinoProcessor`` (image + the phrase, lower-cased and ended with a period as
the model's prompts are) -> ``GroundingDinoForObjectDetection``; a query's score is its highest sigmoid over the
text's tokens (as ``post_process_grounded_object_detection`` computes it, without decoding each box's words), its
box is in frame pixels; a box segmenter (:mod:`drivenav.semantics.boxes`) then turns each box into a mask.

The fusion encoder mixes text and image, so only the two single-modality parts can be reused as SAM3's and OWLv2's
are: the text encoder's output is recorded at a phrase's first forward in the episode and given back to the later
ones, and the Swin backbone's feature maps are computed once per frame; the model's own forward runs the rest, with
those two submodules answering from what was computed (:class:`_Given`), so the result is the plain forward's.
``models.compile`` compiles the backbone, the fusion encoder and the decoder.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import torch
from numpy.typing import NDArray

from drivenav.semantics.boxes import MAX_BOXES, BoxGrounder, BoxSegmenter
from drivenav.semantics.hf_common import load_fast_processor, load_pair

GROUNDING_DINO_EXPECTED = "a local Grounding DINO checkpoint directory or a model id in the Hugging Face cache"
GROUNDING_DINO_CHECKPOINT: Final[str] = "IDEA-Research/grounding-dino-tiny"
"""The default checkpoint: Swin-T with BERT-base, transformers' default configuration."""
GROUNDING_DINO_THRESHOLD: Final[float] = 0.35
"""The box threshold of Grounding DINO's own demonstration (its text threshold, 0.25, names a box's words, which
one phrase does not need)."""


@dataclass
class GroundingDinoText:
    """One phrase's tokens (a batch of one) and the text encoder's output for them, filled at the phrase's first
    forward (``encoded``: its last hidden state, ``(1, T, D)``)."""

    input_ids: Any
    attention_mask: Any
    token_type_ids: Any
    encoded: list[Any] = field(default_factory=list)


@dataclass(frozen=True)
class GroundingDinoVision:
    """A batch of frames' pixels ``(B, 3, H, W)`` and the backbone's feature maps with their masks, per level."""

    pixels: Any
    features: list[tuple[Any, Any]]


class _Given(torch.nn.Module):
    """Stands in for a submodule during one forward, answering every call with ``answer()``."""

    def __init__(self, answer: Any) -> None:
        super().__init__()
        self.answer = answer

    def forward(self, *args: Any, **kwargs: Any) -> Any:
        return self.answer(*args, **kwargs)


@contextlib.contextmanager
def _standing_in(parent: torch.nn.Module, name: str, stand_in: torch.nn.Module) -> Iterator[None]:
    """``parent.name`` replaced by ``stand_in`` for the block."""
    original = getattr(parent, name)
    setattr(parent, name, stand_in)
    try:
        yield
    finally:
        setattr(parent, name, original)


class GroundingDinoGrounder(BoxGrounder):
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with a Grounding DINO checkpoint and a box
    segmenter.

    ``model`` is a checkpoint directory or a cached model id (never downloaded); its processor is loaded with
    torchvision's image processor only (as OWLv2's). Boxes scoring strictly above ``score_threshold`` are kept, at
    most ``max_boxes`` of them, best first. ``dtype``, ``compile_backend``, ``model_obj`` / ``processor_obj`` and
    ``segmenter`` as for :class:`~drivenav.semantics.owlv2_grounder.Owlv2Grounder`.
    """

    name = "grounding-dino"

    def __init__(
        self,
        model: str | Path = GROUNDING_DINO_CHECKPOINT,
        device: str | None = None,
        score_threshold: float = GROUNDING_DINO_THRESHOLD,
        *,
        max_boxes: int = MAX_BOXES,
        dtype: str = "auto",
        compile_backend: str = "",
        model_obj: Any = None,
        processor_obj: Any = None,
        segmenter: BoxSegmenter | None = None,
    ) -> None:
        from transformers import GroundingDinoForObjectDetection, GroundingDinoProcessor

        loaders = (
            GroundingDinoForObjectDetection.from_pretrained,
            load_fast_processor(GroundingDinoProcessor.from_pretrained),
        )
        pair = load_pair(*loaders, model, GROUNDING_DINO_EXPECTED, model_obj, processor_obj)
        super().__init__(*pair, device, dtype, score_threshold, max_boxes, segmenter, compile_backend)

    def compiled_modules(self) -> list[Any]:
        inner = self.model.model
        return [inner.backbone.conv_encoder, inner.encoder, inner.decoder]

    def max_text_tokens(self) -> int:
        """The fusion's text length (``max_text_len``) within the text encoder's positions, less the period the
        processor adds."""
        config = self.model.config
        return int(min(config.max_text_len, config.text_config.max_position_embeddings)) - 1

    def encode_text(self, text: str) -> GroundingDinoText:
        """The tokens of ``text`` as a prompt ("text."; the encoder runs at the first forward)."""
        batch = self.processor(text=[text], return_tensors="pt")
        device = self.model.device
        ids, mask, types = (batch[key].to(device) for key in ("input_ids", "attention_mask", "token_type_ids"))
        return GroundingDinoText(ids, mask, types)

    def encode_vision(self, pixels: Any) -> GroundingDinoVision:
        """The backbone's feature maps of a pixel batch, with the all-valid pixel mask the plain forward makes."""
        batch, _, height, width = pixels.shape
        pixel_mask = torch.ones((batch, height, width), dtype=torch.long, device=pixels.device)
        return GroundingDinoVision(pixels, self.model.model.backbone.conv_encoder(pixels, pixel_mask))

    def decode(self, vision: GroundingDinoVision, text: GroundingDinoText) -> Any:
        """The plain forward, its backbone answering with ``vision``'s feature maps and its text encoder with
        ``text``'s output (recorded now at the phrase's first forward)."""
        batch = vision.pixels.shape[0]
        inner = self.model.model
        text_backbone = inner.text_backbone
        features = _Given(lambda *args, **kwargs: list(vision.features))
        encoder = _Given(lambda *args, **kwargs: _text_output(text_backbone, text, batch, args, kwargs))
        with _standing_in(inner.backbone, "conv_encoder", features), _standing_in(inner, "text_backbone", encoder):
            return self.model(
                pixel_values=vision.pixels,
                input_ids=text.input_ids.expand(batch, -1),
                attention_mask=text.attention_mask.expand(batch, -1),
                token_type_ids=text.token_type_ids.expand(batch, -1),
            )

    def scored_boxes(self, outputs: Any, frames: Sequence[NDArray[np.uint8]]) -> list[tuple[Any, Any]]:
        """Each query's best token probability and its box (centre, size in 0..1) scaled to its frame's pixels."""
        scores = outputs.logits.sigmoid().max(dim=-1).values
        centre, size = outputs.pred_boxes[..., :2], outputs.pred_boxes[..., 2:]
        corners = torch.cat([centre - 0.5 * size, centre + 0.5 * size], dim=-1)
        found = []
        for frame_scores, frame_corners, frame in zip(scores, corners, frames, strict=True):
            height, width = frame.shape[:2]
            scale = torch.tensor([width, height, width, height], dtype=torch.float32, device=frame_corners.device)
            keep = frame_scores > self.score_threshold
            found.append((frame_scores[keep], frame_corners[keep] * scale))
        return found


def _text_output(text_backbone: Any, text: GroundingDinoText, batch: int, args: Any, kwargs: Any) -> Any:
    """The text encoder's output for a batch of ``batch`` copies of ``text``: computed by ``text_backbone`` on the
    forward's own arguments at its first use, recorded, and given back after."""
    from transformers.modeling_outputs import BaseModelOutput

    if not text.encoded:
        text.encoded.append(text_backbone(*args, **kwargs).last_hidden_state[:1])
    return BaseModelOutput(last_hidden_state=text.encoded[0].expand(batch, -1, -1))
