"""SAM3 and OWLv2 without a checkpoint: randomly initialised transformers models with processors built in place.

Two sizes: the tiny test configuration (one layer, 32 features, a 56- or 64-pixel image; a forward takes
milliseconds on a CPU), shared by the grounders' tests and ``bench grounder --tiny``; and the full-size
architecture of transformers' default configuration (``Sam3Config()`` at 1,008 pixels; ``Owlv2Config()``, OWLv2
base/16, at the released checkpoint's 960 pixels), which ``bench grounder`` times when no checkpoint is at hand.
Random weights change no timing: every layer runs whatever its weights are.

No checkpoint means no tokenizer vocabulary either: :func:`letter_tokenizer` is a CLIP BPE tokenizer over letters.
The processors pad every prompt to the text encoder's length (SAM3 32 tokens, OWLv2 16), so the encoders see the
same sequence length as with the real vocabulary. The image processors are torchvision's (fast) ones where
torchvision is installed; without it, OWLv2's PIL processor and, for SAM3 (whose processor is torchvision's only),
:class:`Sam3PilImageProcessor`. This module imports transformers: import it only where the ``models`` extra is.
"""

from __future__ import annotations

import importlib.util
import string
from typing import Any, Final

import torch
from transformers import (
    CLIPTokenizer,
    Owlv2Config,
    Owlv2ForObjectDetection,
    Owlv2ImageProcessorPil,
    Owlv2Processor,
    Sam3Config,
    Sam3Model,
    Sam3Processor,
    ViTImageProcessorPil,
)
from transformers.models.sam3.configuration_sam3 import (
    Sam3DETRDecoderConfig,
    Sam3DETREncoderConfig,
    Sam3GeometryEncoderConfig,
    Sam3MaskDecoderConfig,
    Sam3VisionConfig,
    Sam3ViTConfig,
)

HAS_TORCHVISION: Final[bool] = importlib.util.find_spec("torchvision") is not None

TINY_SAM3_SIZE: Final[int] = 56
"""The tiny SAM3's square input: 4 x 4 patches of 14 pixels."""
TINY_SAM3_QUERIES: Final[int] = 5
TINY_OWL_SIZE: Final[int] = 64
TINY_OWL_PATCH: Final[int] = 8
"""The tiny OWLv2 sees 64 x 64 pixels in 8 x 8 patches: 64 boxes."""

SAM3_IMAGE_SIZE: Final[int] = 1008
"""SAM3's input, in transformers' default configuration and the released facebook/sam3 checkpoint."""
OWLV2_IMAGE_SIZE: Final[int] = 960
"""The released OWLv2 base/16 checkpoint's input (google/owlv2-base-patch16-ensemble's configuration: 60 x 60
patches, 3,600 boxes); transformers' default configuration says 768."""

SAM3_TEXT_TOKENS: Final[int] = 32
OWL_TEXT_TOKENS: Final[int] = 16
"""The text encoders' position tables (SAM3's CLIP text encoder, OWLv2's), also the tiny models'."""

_TEXT: dict[str, Any] = {"vocab_size": 64, "hidden_size": 32, "intermediate_size": 64, "num_hidden_layers": 1}
_TEXT_IDS: dict[str, Any] = {"num_attention_heads": 2, "bos_token_id": 1, "eos_token_id": 2, "pad_token_id": 0}
_LAYER: dict[str, Any] = {"hidden_size": 32, "num_layers": 1, "num_attention_heads": 2, "intermediate_size": 64}


def letter_tokenizer(max_length: int) -> CLIPTokenizer:
    """Byte-level BPE without merges: ids 0-2 are pad ("!", as OWLv2's), bos, eos; then two ids per letter.

    bos must not be id 0: OWLv2 treats a query whose first token is 0 as padding and masks it out.
    """
    vocab = {"!": 0, "<|startoftext|>": 1, "<|endoftext|>": 2}
    for letter in string.ascii_lowercase:
        vocab[letter] = len(vocab)
        vocab[letter + "</w>"] = len(vocab)
    return CLIPTokenizer(vocab=vocab, merges=[], pad_token="!", model_max_length=max_length)


def tiny_sam3_config() -> Sam3Config:
    backbone = Sam3ViTConfig(
        hidden_size=32,
        intermediate_size=64,
        num_hidden_layers=1,
        num_attention_heads=2,
        image_size=TINY_SAM3_SIZE,
        patch_size=14,
        window_size=2,
        global_attn_indexes=[0],
        pretrain_image_size=TINY_SAM3_SIZE,
    )
    return Sam3Config(
        vision_config=Sam3VisionConfig(backbone_config=backbone, fpn_hidden_size=32, scale_factors=[2.0, 1.0]),
        text_config={**_TEXT, **_TEXT_IDS, "projection_dim": 32, "max_position_embeddings": SAM3_TEXT_TOKENS},
        geometry_encoder_config=Sam3GeometryEncoderConfig(**_LAYER),
        detr_encoder_config=Sam3DETREncoderConfig(**_LAYER),
        detr_decoder_config=Sam3DETRDecoderConfig(**_LAYER, num_queries=TINY_SAM3_QUERIES),
        mask_decoder_config=Sam3MaskDecoderConfig(hidden_size=32, num_upsampling_stages=2, num_attention_heads=2),
    )


def tiny_owlv2_config() -> Owlv2Config:
    return Owlv2Config(
        text_config={**_TEXT, **_TEXT_IDS, "max_position_embeddings": OWL_TEXT_TOKENS},
        vision_config={
            "hidden_size": 32,
            "intermediate_size": 64,
            "num_hidden_layers": 1,
            "num_attention_heads": 2,
            "image_size": TINY_OWL_SIZE,
            "patch_size": TINY_OWL_PATCH,
        },
        projection_dim=32,
    )


class Sam3PilImageProcessor(ViTImageProcessorPil):
    """SAM3's image processor without torchvision: bilinear resize to a square, 1/255, mean = std = 0.5 (what
    ``Sam3ImageProcessor`` does), on ViT's PIL backend.

    Its instance post-processing follows the SAM3 documentation: score = sigmoid(query logit) * sigmoid(presence
    logit), kept when strictly above the threshold; mask = bilinear-resized mask probability above mask_threshold.
    """

    def preprocess(self, images: Any, segmentation_maps: Any = None, **kwargs: Any) -> Any:
        return super().preprocess(images, **kwargs)

    def post_process_instance_segmentation(
        self, outputs: Any, threshold: float, mask_threshold: float, target_sizes: list[tuple[int, int]]
    ) -> list[dict[str, torch.Tensor]]:
        scores = outputs.pred_logits.sigmoid() * outputs.presence_logits.sigmoid()
        results = []
        for image_scores, image_masks, size in zip(scores, outputs.pred_masks, target_sizes, strict=True):
            keep = image_scores > threshold
            probs = torch.nn.functional.interpolate(image_masks[None].sigmoid(), size=size, mode="bilinear")[0]
            results.append({"scores": image_scores[keep], "masks": (probs[keep] > mask_threshold).long()})
        return results


def sam3_processor(size: int) -> Sam3Processor:
    """A SAM3 processor for ``size``-pixel square inputs: torchvision's image processor, else the PIL stand-in."""
    if HAS_TORCHVISION:
        from transformers import Sam3ImageProcessor

        image_processor: Any = Sam3ImageProcessor(size={"height": size, "width": size})
    else:
        image_processor = Sam3PilImageProcessor(size={"height": size, "width": size})
    return Sam3Processor(image_processor=image_processor, tokenizer=letter_tokenizer(SAM3_TEXT_TOKENS))


def owlv2_processor(size: int) -> Owlv2Processor:
    """An OWLv2 processor for ``size``-pixel square inputs: torchvision's image processor, else the PIL one."""
    if HAS_TORCHVISION:
        from transformers import Owlv2ImageProcessor

        image_processor: Any = Owlv2ImageProcessor(size={"height": size, "width": size})
    else:
        image_processor = Owlv2ImageProcessorPil(size={"height": size, "width": size})
    tokenizer = letter_tokenizer(OWL_TEXT_TOKENS)
    return Owlv2Processor(image_processor=image_processor, tokenizer=tokenizer)  # type: ignore[no-untyped-call]


def random_sam3(tiny: bool) -> tuple[Any, Any]:
    """A randomly initialised SAM3 (tiny, or transformers' default configuration) and its processor."""
    model: Any = Sam3Model(tiny_sam3_config() if tiny else Sam3Config())
    return model.eval(), sam3_processor(TINY_SAM3_SIZE if tiny else SAM3_IMAGE_SIZE)


def random_owlv2(tiny: bool) -> tuple[Any, Any]:
    """A randomly initialised OWLv2 (tiny, or transformers' default base/16 configuration at the released
    checkpoint's :data:`OWLV2_IMAGE_SIZE`) and its processor."""
    config = tiny_owlv2_config() if tiny else Owlv2Config(vision_config={"image_size": OWLV2_IMAGE_SIZE})
    model: Any = Owlv2ForObjectDetection(config)
    return model.eval(), owlv2_processor(TINY_OWL_SIZE if tiny else OWLV2_IMAGE_SIZE)
