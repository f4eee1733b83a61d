"""Grounding DINO boxes turned into masks: the detector of VLFM and ApexNav, the paper's peers (Sec. V-D).

Grounding DINO (Liu et al., ECCV 2024) grounds a text in an image with a Swin backbone, a BERT text encoder, an
encoder that fuses the image and text features, and a DETR decoder whose queries are scored against each text
token. Through transformers: ``GroundingDinoProcessor`` (image + the phrase, lower-cased and ended with a period as
the model's prompts are) -> ``GroundingDinoForObjectDetection``; a query's score is its highest sigmoid over the
text's tokens (as ``post_process_grounded_object_detection`` computes it, without decoding each box's words), its
box is in frame pixels; a box segmenter (:mod:`drivenav.semantics.boxes`) then turns each box into a mask.

The fusion encoder mixes text and image, so only the two single-modality parts can be reused as SAM3's and OWLv2's
are: the text encoder's output is computed once per phrase and episode (as the plain forward computes it), and the
Swin backbone's feature maps once per frame; the model's own forward runs the rest, with those two submodules
answering from what was computed (:class:`_Given`), so the result is the plain forward's. Rows with different
phrases run in one forward with their prompts padded to the longest, as transformers batches prompts.
``models.compile`` compiles the backbone, the fusion encoder and the decoder.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
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


@dataclass(frozen=True)
class GroundingDinoText:
    """One phrase's prompt tokens (a batch of one: ids, attention mask, token types) and the text encoder's output
    for them (``encoded``: its last hidden state, ``(1, T, D)``)."""

    input_ids: Any
    attention_mask: Any
    token_type_ids: Any
    encoded: Any


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
        """The tokens of ``text`` as a prompt ("text.") and the text encoder's output for them, computed as the plain
        forward computes it: on the attention mask and position ids it derives from the delimiter tokens."""
        from transformers.models.grounding_dino.modeling_grounding_dino import (
            generate_masks_with_special_tokens_and_transfer_map as delimited,
        )

        batch = self.processor(text=[text], return_tensors="pt")
        device = self.model.device
        ids, mask, types = (batch[key].to(device) for key in ("input_ids", "attention_mask", "token_type_ids"))
        inner = self.model.model
        blocks, positions = delimited(ids, inner.special_tokens)
        encoded = inner.text_backbone(ids, blocks[:, None], types, positions, return_dict=True).last_hidden_state
        return GroundingDinoText(ids, mask, types, encoded)

    def encode_vision(self, pixels: Any) -> GroundingDinoVision:
        """The backbone's feature maps of a pixel batch, with the all-valid pixel mask the plain forward makes."""
        batch, _, height, width = pixels.shape
        pixel_mask = torch.ones((batch, height, width), dtype=torch.long, device=pixels.device)
        return GroundingDinoVision(pixels, self.model.model.backbone.conv_encoder(pixels, pixel_mask))

    def decode_rows(self, vision: GroundingDinoVision, texts: Sequence[GroundingDinoText]) -> Any:
        """The plain forward over the rows, each row's prompt padded to the longest one (pad tokens masked out, as
        in a batch of prompts), its backbone answering with ``vision``'s feature maps and its text encoder with each
        row's encoded phrase."""
        from transformers.modeling_outputs import BaseModelOutput

        length = max(text.input_ids.shape[1] for text in texts)
        encoded = _padded([text.encoded for text in texts], length)
        inner = self.model.model
        features = _Given(lambda *args, **kwargs: list(vision.features))
        encoder = _Given(lambda *args, **kwargs: BaseModelOutput(last_hidden_state=encoded))
        with _standing_in(inner.backbone, "conv_encoder", features), _standing_in(inner, "text_backbone", encoder):
            return self.model(
                pixel_values=vision.pixels,
                input_ids=_padded([text.input_ids for text in texts], length),
                attention_mask=_padded([text.attention_mask for text in texts], length),
                token_type_ids=_padded([text.token_type_ids for text in texts], length),
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


def _padded(rows: Sequence[Any], length: int) -> Any:
    """Rows of one phrase each (``(1, T, ...)``) right-padded with zeros to ``length`` tokens, stacked (zero is the
    pad token, and a pad's attention mask)."""
    return torch.cat(
        [torch.nn.functional.pad(row, (0, 0) * (row.dim() - 2) + (0, length - row.shape[1])) for row in rows]
    )
