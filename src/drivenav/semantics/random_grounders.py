"""SAM3, OWLv2, Grounding DINO and MobileSAM without a checkpoint: randomly initialised models with processors built
in place.

Two sizes: the tiny test configuration (one or two layers, 32 features, an image of 56-64 pixels; a forward takes
milliseconds on a CPU), shared by the grounders' tests and ``bench grounder --tiny``; and the full-size
architecture of transformers' default configuration (``Sam3Config()`` at 1,008 pixels; ``Owlv2Config()``, OWLv2
base/16, at the released checkpoint's 960 pixels; ``GroundingDinoConfig()``, Swin-T and BERT-base, Grounding DINO
tiny) and MobileSAM's ``vit_t``, which ``bench grounder`` and ``serve grounder --random-weights`` run when no
checkpoint is at hand. Random weights change no timing: every layer runs whatever its weights are (the number of
boxes a detector passes to MobileSAM is the exception: the bench says how many it segmented). The models are built
on the device they will run on (initialising SAM3's 850 M weights on a CPU takes longer than a benchmark).

No checkpoint means no tokenizer vocabulary either: :func:`letter_tokenizer` is a CLIP BPE tokenizer over letters,
:func:`bert_letter_tokenizer` a WordPiece one (Grounding DINO's text encoder is BERT). The CLIP processors pad every
prompt to the text encoder's length (SAM3 32 tokens, OWLv2 16), so the encoders see the same sequence length as
with the real vocabulary; Grounding DINO's does not pad, and a letter is a token, so its prompts are a few tokens
longer than with BERT's words. The image processors are torchvision's (fast) ones where torchvision is installed;
without it, OWLv2's and Grounding DINO's PIL processors and, for SAM3 (whose processor is torchvision's only),
:class:`Sam3PilImageProcessor`. This module imports transformers: import it only where the ``models`` extra is.
"""

from __future__ import annotations

import contextlib
import importlib.util
import string
from collections.abc import Callable, Iterator
from typing import Any, Final

import torch
from transformers import (
    BertTokenizer,
    CLIPTokenizer,
    GroundingDinoConfig,
    GroundingDinoForObjectDetection,
    GroundingDinoProcessor,
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

from drivenav.semantics import mobilesam_segmenter
from drivenav.semantics.boxes import BoxSegmenter, FilledBoxSegmenter
from drivenav.semantics.grounding_dino_grounder import GroundingDinoGrounder
from drivenav.semantics.hf_common import TransformersGrounder, compile_backend_for, pick_device
from drivenav.semantics.mobilesam_segmenter import MobileSamSegmenter
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.owlv2_grounder import Owlv2Grounder
from drivenav.semantics.registry import BOX_DETECTORS
from drivenav.semantics.sam3_grounder import Sam3Grounder

HAS_TORCHVISION: Final[bool] = importlib.util.find_spec("torchvision") is not None

TINY_SAM3_SIZE: Final[int] = 56
"""The tiny SAM3's square input: 4 x 4 patches of 14 pixels."""
TINY_SAM3_QUERIES: Final[int] = 5
TINY_OWL_SIZE: Final[int] = 64
TINY_OWL_PATCH: Final[int] = 8
"""The tiny OWLv2 sees 64 x 64 pixels in 8 x 8 patches: 64 boxes."""
TINY_GROUNDING_DINO_QUERIES: Final[int] = 10
TINY_GROUNDING_DINO_SIZE: Final[dict[str, int]] = {"shortest_edge": 64, "longest_edge": 96}
"""The tiny Grounding DINO's image: the short side at 64 pixels, the long one at most 96 (the released one's 800 and
1,333)."""

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


BERT_SPECIAL_IDS: Final[dict[str, int]] = {"[PAD]": 0, "[UNK]": 100, "[CLS]": 101, "[SEP]": 102, "[MASK]": 103}
BERT_PUNCTUATION_IDS: Final[dict[str, int]] = {".": 1012, "?": 1029}
"""BERT-base-uncased's ids of its special tokens and of the two punctuation marks Grounding DINO splits a prompt at
(the model's forward names these ids, so the letter vocabulary keeps them)."""
BERT_LETTER_VOCAB: Final[int] = 1030
"""The letter vocabulary's size: every id up to "?" (unused ids are placeholders)."""


def bert_letter_tokenizer() -> BertTokenizer:
    """WordPiece over letters (a word is its first letter, then "##" and one letter each) with BERT's special and
    punctuation ids."""
    tokens = {**BERT_SPECIAL_IDS, **BERT_PUNCTUATION_IDS}
    for k, letter in enumerate(string.ascii_lowercase):
        tokens[letter] = 200 + k
        tokens["##" + letter] = 300 + k
    names = {i: name for name, i in tokens.items()}
    vocab = {names.get(i, f"[unused{i}]"): i for i in range(BERT_LETTER_VOCAB)}
    return BertTokenizer(vocab=vocab)


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


def tiny_grounding_dino_config() -> GroundingDinoConfig:
    """Swin with 16 features and three one-layer stages (two feature levels, a third made by the model), a
    one-layer BERT and fusion encoder, a two-layer decoder (one would leave its tied box heads empty), 32 features
    (the input projections' group norm takes 32 groups)."""
    from transformers import SwinConfig

    stages: dict[str, Any] = {"depths": [1, 1, 1], "num_heads": [1, 1, 1], "out_features": ["stage2", "stage3"]}
    backbone = SwinConfig(image_size=64, patch_size=4, embed_dim=16, window_size=2, **stages)
    return GroundingDinoConfig(
        backbone_config=backbone,
        d_model=32,
        encoder_layers=1,
        decoder_layers=2,
        encoder_ffn_dim=64,
        decoder_ffn_dim=64,
        encoder_attention_heads=2,
        decoder_attention_heads=2,
        num_queries=TINY_GROUNDING_DINO_QUERIES,
        num_feature_levels=3,
        encoder_n_points=2,
        decoder_n_points=2,
        text_config={
            "model_type": "bert",
            "vocab_size": BERT_LETTER_VOCAB,
            "hidden_size": 32,
            "num_hidden_layers": 1,
            "num_attention_heads": 2,
            "intermediate_size": 64,
        },
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


def grounding_dino_processor(tiny: bool) -> GroundingDinoProcessor:
    """A Grounding DINO processor (the tiny image size, or the released 800 / 1,333): torchvision's image processor,
    else the PIL one."""
    size = TINY_GROUNDING_DINO_SIZE if tiny else {"shortest_edge": 800, "longest_edge": 1333}
    if HAS_TORCHVISION:
        from transformers import GroundingDinoImageProcessor

        image_processor: Any = GroundingDinoImageProcessor(size=size)
    else:
        from transformers import GroundingDinoImageProcessorPil

        image_processor = GroundingDinoImageProcessorPil(size=size)
    tokenizer = bert_letter_tokenizer()
    return GroundingDinoProcessor(image_processor=image_processor, tokenizer=tokenizer)  # type: ignore[no-untyped-call]


def random_sam3(tiny: bool, device: str = "cpu") -> tuple[Any, Any]:
    """A randomly initialised SAM3 (tiny, or transformers' default configuration) on ``device`` and its processor."""
    with torch.device(device):
        model: Any = Sam3Model(tiny_sam3_config() if tiny else Sam3Config())
    return model.eval(), sam3_processor(TINY_SAM3_SIZE if tiny else SAM3_IMAGE_SIZE)


def random_owlv2(tiny: bool, device: str = "cpu") -> tuple[Any, Any]:
    """A randomly initialised OWLv2 (tiny, or transformers' default base/16 configuration at the released
    checkpoint's :data:`OWLV2_IMAGE_SIZE`) on ``device`` and its processor."""
    config = tiny_owlv2_config() if tiny else Owlv2Config(vision_config={"image_size": OWLV2_IMAGE_SIZE})
    with torch.device(device):
        model: Any = Owlv2ForObjectDetection(config)
    return model.eval(), owlv2_processor(TINY_OWL_SIZE if tiny else OWLV2_IMAGE_SIZE)


def random_grounding_dino(tiny: bool, device: str = "cpu") -> tuple[Any, Any]:
    """A randomly initialised Grounding DINO (tiny, or transformers' default configuration: Swin-T, BERT-base) on
    ``device`` and its processor."""
    with torch.device(device):
        model: Any = GroundingDinoForObjectDetection(tiny_grounding_dino_config() if tiny else GroundingDinoConfig())
    return model.eval(), grounding_dino_processor(tiny)


def random_mobile_sam(tiny: bool, device: str = "cpu") -> mobilesam_segmenter.MobileSamModel:
    """A randomly initialised MobileSAM on ``device``: the tests' tiny architecture, or the released ``vit_t``
    (which needs timm)."""
    with torch.device(device):
        return mobilesam_segmenter.build_architecture("tiny" if tiny else "vit_t")


RANDOM_DETECTORS: dict[str, Callable[[bool, str], tuple[Any, Any]]] = {
    "sam3": random_sam3,
    "owlv2": random_owlv2,
    "grounding-dino": random_grounding_dino,
}
"""The transformers detectors, randomly initialised (``tiny``, ``device``) with their processors."""
GROUNDERS: dict[str, Callable[..., TransformersGrounder]] = {
    "sam3": Sam3Grounder,
    "owlv2": Owlv2Grounder,
    "grounding-dino": GroundingDinoGrounder,
}
"""The grounder of each transformers detector."""


RANDOM_WEIGHTS_SEED: Final[int] = 0
"""The seed of the random weights that ``bench grounder``, ``bench eval-throughput`` and ``serve grounder
--random-weights`` / ``--tiny`` build (:func:`random_grounder`, :func:`random_segmenter`): the same weights in every
run and in every copy a server runs (``--copies``), so that a served frame's detections do not depend on the copy
that grounded it, and the detections a frame, which a reply's cost follows, are the same from run to run."""


@contextlib.contextmanager
def seeded_weights(device: str) -> Iterator[None]:
    """torch's generators (the CPU's and, on CUDA, ``device``'s) seeded with :data:`RANDOM_WEIGHTS_SEED` within the
    block, and as they were after it."""
    chosen = torch.device(device)
    cuda = [chosen.index if chosen.index is not None else torch.cuda.current_device()] if chosen.type == "cuda" else []
    with torch.random.fork_rng(devices=cuda):
        torch.manual_seed(RANDOM_WEIGHTS_SEED)
        yield


def random_segmenter(spec: ModelSpec, tiny: bool) -> BoxSegmenter:
    """``spec``'s box segmenter, MobileSAM with random weights (tiny or ``vit_t``, :func:`seeded_weights`) placed as
    ``spec`` says."""
    if spec.segmenter == "filled-box":
        return FilledBoxSegmenter()
    device = pick_device(spec.detector_device or None)
    with seeded_weights(device):
        model = random_mobile_sam(tiny, device)
    return MobileSamSegmenter(model, device, spec.dtype, compile_backend_for(spec.compile))


def random_grounder(spec: ModelSpec, tiny: bool, segmenter: BoxSegmenter | None = None) -> TransformersGrounder:
    """``spec``'s detector (one of :data:`RANDOM_DETECTORS`) with random weights (:func:`seeded_weights`), on
    ``spec``'s device in its dtype, compiled when it says; a box detector's segmenter is ``segmenter``, else
    ``spec``'s with random weights."""
    device = pick_device(spec.detector_device or None)
    with seeded_weights(device):
        model, processor = RANDOM_DETECTORS[spec.detector](tiny, device)
    options: dict[str, Any] = {"dtype": spec.dtype, "compile_backend": compile_backend_for(spec.compile)}
    if spec.detector in BOX_DETECTORS:
        options["segmenter"] = segmenter if segmenter is not None else random_segmenter(spec, tiny)
    grounder: TransformersGrounder = GROUNDERS[spec.detector](
        device=device, model_obj=model, processor_obj=processor, **options
    )
    return grounder
