"""The SAM3 and OWLv2 grounders end to end on tiny randomly initialised transformers models (no downloads).

Both tokenizers are CLIP BPE tokenizers over a 55-entry character vocabulary. OWLv2 runs with its real processor
(the PIL image backend). SAM3's real image processor needs torchvision; where it is missing, a stand-in with the
same resize / rescale / normalise steps (ViT's PIL backend) and SAM3's documented instance post-processing is
plugged into the real ``Sam3Processor``.
"""

from __future__ import annotations

import importlib.util
import string
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("transformers")

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

from drivenav.errors import InputError
from drivenav.semantics.hf_common import fit_phrase, load_local, pick_device
from drivenav.semantics.owlv2_grounder import FilledBoxSegmenter, Owlv2Grounder
from drivenav.semantics.protocols import Detection, Grounder
from drivenav.semantics.sam3_grounder import Sam3Grounder
from drivenav.types import CameraIntrinsics, Observation, Pose

H, W = 48, 64  # the frame; both models see a square image of SAM3_SIZE / OWL_SIZE pixels
SAM3_SIZE = 56  # 4 x 4 patches of 14 pixels
SAM3_QUERIES = 5
OWL_SIZE, OWL_PATCH = 64, 8
OWL_BOXES = (OWL_SIZE // OWL_PATCH) ** 2  # one box per patch
HAS_TORCHVISION = importlib.util.find_spec("torchvision") is not None


def tiny_tokenizer(max_length: int) -> CLIPTokenizer:
    """Byte-level BPE without merges: ids 0-2 are pad ("!", as OWLv2's), bos, eos; then two ids per letter.

    bos must not be id 0: OWLv2 treats a query whose first token is 0 as padding and masks it out.
    """
    vocab = {"!": 0, "<|startoftext|>": 1, "<|endoftext|>": 2}
    for letter in string.ascii_lowercase:
        vocab[letter] = len(vocab)
        vocab[letter + "</w>"] = len(vocab)
    return CLIPTokenizer(vocab=vocab, merges=[], pad_token="!", model_max_length=max_length)


TEXT = {"vocab_size": 64, "hidden_size": 32, "intermediate_size": 64, "num_hidden_layers": 1}
TEXT_IDS = {"num_attention_heads": 2, "bos_token_id": 1, "eos_token_id": 2, "pad_token_id": 0}
LAYER = {"hidden_size": 32, "num_layers": 1, "num_attention_heads": 2, "intermediate_size": 64}


def tiny_sam3_config() -> Sam3Config:
    backbone = Sam3ViTConfig(
        hidden_size=32,
        intermediate_size=64,
        num_hidden_layers=1,
        num_attention_heads=2,
        image_size=SAM3_SIZE,
        patch_size=14,
        window_size=2,
        global_attn_indexes=[0],
        pretrain_image_size=SAM3_SIZE,
    )
    return Sam3Config(
        vision_config=Sam3VisionConfig(backbone_config=backbone, fpn_hidden_size=32, scale_factors=[2.0, 1.0]),
        text_config={**TEXT, **TEXT_IDS, "projection_dim": 32, "max_position_embeddings": 32},
        geometry_encoder_config=Sam3GeometryEncoderConfig(**LAYER),
        detr_encoder_config=Sam3DETREncoderConfig(**LAYER),
        detr_decoder_config=Sam3DETRDecoderConfig(**LAYER, num_queries=SAM3_QUERIES),
        mask_decoder_config=Sam3MaskDecoderConfig(hidden_size=32, num_upsampling_stages=2, num_attention_heads=2),
    )


class Sam3StandInImageProcessor(ViTImageProcessorPil):
    """Sam3ImageProcessor without torchvision: bilinear resize to a square, 1/255, mean = std = 0.5.

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


def sam3_image_processor() -> Any:
    if HAS_TORCHVISION:
        from transformers import Sam3ImageProcessor

        return Sam3ImageProcessor(size={"height": SAM3_SIZE, "width": SAM3_SIZE})
    return Sam3StandInImageProcessor(size={"height": SAM3_SIZE, "width": SAM3_SIZE})


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread() -> Iterator[None]:
    """Tiny models gain nothing from threads; on shared cores extra threads only oversubscribe them."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def sam3() -> tuple[Sam3Model, Sam3Processor]:
    torch.manual_seed(0)
    processor = Sam3Processor(image_processor=sam3_image_processor(), tokenizer=tiny_tokenizer(32))
    return Sam3Model(tiny_sam3_config()).eval(), processor


@pytest.fixture(scope="module")
def owl() -> tuple[Owlv2ForObjectDetection, Owlv2Processor]:
    """A tiny OWLv2 whose box regressor outputs zero, so each patch's box is its prior: centred on the patch's
    bottom-right corner, one patch wide (a random regressor saturates the sigmoid into degenerate boxes)."""
    torch.manual_seed(0)
    config = Owlv2Config(
        text_config={**TEXT, **TEXT_IDS, "max_position_embeddings": 16},
        vision_config={
            "hidden_size": 32,
            "intermediate_size": 64,
            "num_hidden_layers": 1,
            "num_attention_heads": 2,
            "image_size": OWL_SIZE,
            "patch_size": OWL_PATCH,
        },
        projection_dim=32,
    )
    model = Owlv2ForObjectDetection(config).eval()
    with torch.no_grad():
        model.box_head.dense2.weight.zero_()
        model.box_head.dense2.bias.zero_()
    image_processor = Owlv2ImageProcessorPil(size={"height": OWL_SIZE, "width": OWL_SIZE})
    return model, Owlv2Processor(image_processor=image_processor, tokenizer=tiny_tokenizer(16))


def observation(seed: int = 0) -> Observation:
    return Observation(
        rgb=np.random.default_rng(seed).integers(0, 256, (H, W, 3), dtype=np.uint8),
        depth=np.full((H, W), 2.0, np.float32),
        semantic=None,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(W, H, 79.0),
        step=0,
        collided=False,
    )


def sam3_grounder(sam3: tuple[Sam3Model, Sam3Processor], threshold: float) -> Sam3Grounder:
    model, processor = sam3
    return Sam3Grounder(device="cpu", score_threshold=threshold, model_obj=model, processor_obj=processor)


def owl_grounder(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor], threshold: float, **kwargs: Any) -> Owlv2Grounder:
    model, processor = owl
    return Owlv2Grounder(device="cpu", score_threshold=threshold, model_obj=model, processor_obj=processor, **kwargs)


def assert_well_formed(detections: list[Detection], phrase: str) -> None:
    scores = [d.score for d in detections]
    assert scores == sorted(scores, reverse=True)
    assert all(0.0 <= s <= 1.0 for s in scores)
    for d in detections:
        assert d.phrase == phrase
        assert d.mask.dtype == np.bool_ and d.mask.shape == (H, W) and d.mask.any()


def same_detections(a: list[Detection], b: list[Detection]) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.mask, y.mask) and x.score == pytest.approx(y.score, abs=1e-6)
        for x, y in zip(a, b, strict=True)
    )


def area(rectangle: tuple[int, int, int, int]) -> int:
    row0, row1, col0, col1 = rectangle
    return (row1 - row0) * (col1 - col0)


def bounding_rectangle(mask: np.ndarray) -> tuple[int, int, int, int]:
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


# --- SAM3 ---


def test_sam3_satisfies_the_grounder_protocol(sam3: tuple[Sam3Model, Sam3Processor]) -> None:
    grounder: Grounder = sam3_grounder(sam3, 0.5)
    assert grounder.name == "sam3"
    grounder.begin_episode({1: "chair"}, seed=3)


def test_sam3_threshold_zero_keeps_every_query_with_a_mask(sam3: tuple[Sam3Model, Sam3Processor]) -> None:
    detections = sam3_grounder(sam3, 0.0).segment(observation(), "red chair")
    assert 0 < len(detections) <= SAM3_QUERIES
    assert_well_formed(detections, "red chair")


def test_sam3_score_threshold_is_strict_and_really_filters(sam3: tuple[Sam3Model, Sam3Processor]) -> None:
    everything = sam3_grounder(sam3, 0.0).segment(observation(), "chair")
    best = everything[0].score
    just_below = sam3_grounder(sam3, best - 1e-6).segment(observation(), "chair")
    assert same_detections(just_below, everything[:1])
    assert sam3_grounder(sam3, best).segment(observation(), "chair") == []
    assert sam3_grounder(sam3, 1.0).segment(observation(), "chair") == []


def test_sam3_mask_threshold_grows_and_shrinks_the_masks(sam3: tuple[Sam3Model, Sam3Processor]) -> None:
    model, processor = sam3
    loose, tight = (
        Sam3Grounder(device="cpu", score_threshold=0.0, mask_threshold=t, model_obj=model, processor_obj=processor)
        for t in (0.0, 0.9999)
    )
    assert all(d.mask.all() for d in loose.segment(observation(), "chair"))
    assert tight.segment(observation(), "chair") == []  # empty masks are dropped


def test_sam3_loads_weights_from_a_saved_directory(sam3: tuple[Sam3Model, Sam3Processor], tmp_path: Path) -> None:
    model, processor = sam3
    model.save_pretrained(tmp_path)
    loaded = Sam3Grounder(tmp_path, device="cpu", score_threshold=0.0, processor_obj=processor)
    assert loaded.model is not model
    assert same_detections(
        loaded.segment(observation(), "chair"), sam3_grounder(sam3, 0.0).segment(observation(), "chair")
    )


@pytest.mark.skipif(HAS_TORCHVISION, reason="checks the error without torchvision")
def test_sam3_checkpoint_without_torchvision_says_so(sam3: tuple[Sam3Model, Sam3Processor], tmp_path: Path) -> None:
    """Not an InputError: the checkpoint is there, the image processor's backend is not."""
    sam3[0].save_pretrained(tmp_path)
    (tmp_path / "processor_config.json").write_text('{"processor_class": "Sam3Processor"}')
    (tmp_path / "preprocessor_config.json").write_text('{"image_processor_type": "Sam3ImageProcessor"}')
    sam3[1].tokenizer.save_pretrained(tmp_path)
    with pytest.raises(ValueError, match="Missing optional dependencies: torchvision"):
        Sam3Grounder(tmp_path, device="cpu")


# --- OWLv2 ---


def test_owlv2_satisfies_the_grounder_protocol(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor]) -> None:
    grounder: Grounder = owl_grounder(owl, 0.1)
    assert grounder.name == "owlv2"
    grounder.begin_episode(None, seed=0)


def test_owlv2_box_masks_are_the_patch_priors_inside_the_frame(
    owl: tuple[Owlv2ForObjectDetection, Owlv2Processor],
) -> None:
    """The frame is padded to a 64 x 64 square: box (i, j) covers rows 8j-4..8j+4 and columns 8i-4..8i+4 of it;
    rows past 48 are padding, so the boxes of the last two patch rows vanish and the sixth row is cut at 48."""
    detections = owl_grounder(owl, 0.0).segment(observation(), "chair")
    assert_well_formed(detections, "chair")
    rectangles = {bounding_rectangle(d.mask) for d in detections}
    expected = {(8 * j - 4, min(8 * j + 4, H), 8 * i - 4, min(8 * i + 4, W)) for i in range(1, 9) for j in range(1, 7)}
    assert len(detections) == len(rectangles) == 48
    assert rectangles == expected
    assert all(d.mask.sum() == area(bounding_rectangle(d.mask)) for d in detections)  # filled rectangles


def test_owlv2_score_threshold_is_strict_and_really_filters(
    owl: tuple[Owlv2ForObjectDetection, Owlv2Processor],
) -> None:
    everything = owl_grounder(owl, 0.0).segment(observation(), "chair")
    scores = [d.score for d in everything]
    median = float(np.median(scores))
    assert {d.score for d in owl_grounder(owl, median).segment(observation(), "chair")} == {
        s for s in scores if s > median
    }
    assert owl_grounder(owl, scores[0]).segment(observation(), "chair") == []
    assert owl_grounder(owl, 1.0).segment(observation(), "chair") == []


class TopRowSegmenter:
    """A box segmenter that keeps only the top pixel row of each filled box and records its calls."""

    def __init__(self) -> None:
        self.calls: list[np.ndarray] = []

    def segment_boxes(self, rgb: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        self.calls.append(boxes)
        masks = FilledBoxSegmenter().segment_boxes(rgb, boxes)
        return masks & (np.cumsum(masks, axis=1) == 1)


def test_owlv2_uses_the_given_box_segmenter(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor]) -> None:
    segmenter = TopRowSegmenter()
    detections = owl_grounder(owl, 0.0, segmenter=segmenter).segment(observation(), "chair")
    assert len(segmenter.calls) == 1 and segmenter.calls[0].shape == (OWL_BOXES, 4)
    assert len(detections) == 48
    assert all(bounding_rectangle(d.mask)[1] - bounding_rectangle(d.mask)[0] == 1 for d in detections)


def test_owlv2_rejects_masks_of_the_wrong_shape(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor]) -> None:
    class Transposed:
        def segment_boxes(self, rgb: np.ndarray, boxes: np.ndarray) -> np.ndarray:
            return np.ones((len(boxes), W, H), bool)

    with pytest.raises(ValueError, match="shape"):
        owl_grounder(owl, 0.0, segmenter=Transposed()).segment(observation(), "chair")


def test_filled_box_segmenter_takes_pixels_whose_centre_is_inside() -> None:
    rgb = np.zeros((4, 6, 3), np.uint8)
    boxes = np.array(
        [[0.0, 0.0, 6.0, 4.0], [1.4, 0.4, 3.6, 2.6], [-5.0, 3.2, 2.0, 9.0], [2.0, 1.0, 2.4, 3.0]], np.float32
    )
    masks = FilledBoxSegmenter().segment_boxes(rgb, boxes)
    assert masks.shape == (4, 4, 6) and masks.dtype == np.bool_
    assert masks[0].all()
    assert [bounding_rectangle(m) for m in masks[1:3]] == [(0, 3, 1, 4), (3, 4, 0, 2)]
    assert masks[1].sum() == 9 and masks[2].sum() == 2
    assert not masks[3].any()  # narrower than a pixel and missing every centre


def test_owlv2_loads_model_and_processor_from_a_saved_directory(
    owl: tuple[Owlv2ForObjectDetection, Owlv2Processor], tmp_path: Path
) -> None:
    model, processor = owl
    model.save_pretrained(tmp_path)
    processor.save_pretrained(tmp_path)
    loaded = Owlv2Grounder(str(tmp_path), device="cpu", score_threshold=0.0)
    assert loaded.model is not model and loaded.processor is not processor
    assert same_detections(
        loaded.segment(observation(), "chair"), owl_grounder(owl, 0.0).segment(observation(), "chair")
    )


# --- missing weights, loading, device ---


@pytest.mark.parametrize("grounder", [Sam3Grounder, Owlv2Grounder])
@pytest.mark.parametrize("where", ["missing", "empty", "no-such-org/no-such-model"])
def test_missing_weights_are_a_one_line_input_error(grounder: Any, where: str, tmp_path: Path) -> None:
    model = {"missing": str(tmp_path / "nowhere"), "empty": str(tmp_path), "no-such-org/no-such-model": where}[where]
    with pytest.raises(InputError) as caught:
        grounder(model, device="cpu")
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith("command line: field '--detector-model': expected a local ")
    assert "checkpoint directory or a model id in the Hugging Face cache" in message
    assert model[:40] in message  # InputError shortens a long value from its end


def test_loading_never_downloads() -> None:
    seen: dict[str, Any] = {}

    def loader(name: str, **kwargs: Any) -> str:
        seen.update(kwargs, name=name)
        return "loaded"

    assert load_local(loader, Path("/some/dir"), "anything") == "loaded"
    assert seen == {"name": "/some/dir", "local_files_only": True}


def test_device_defaults_to_cuda_only_when_visible() -> None:
    assert pick_device("cpu") == "cpu"
    assert pick_device(None) == ("cuda" if torch.cuda.is_available() else "cpu")


LONG_PHRASE = "tall wooden bookshelf near the window"  # 37 characters: one token per letter here


@pytest.mark.parametrize("which", ["sam3", "owlv2"])
def test_a_phrase_longer_than_the_text_encoder_still_grounds(
    which: str, sam3: tuple[Sam3Model, Sam3Processor], owl: tuple[Owlv2ForObjectDetection, Owlv2Processor]
) -> None:
    grounder = sam3_grounder(sam3, 0.0) if which == "sam3" else owl_grounder(owl, 0.0)
    detections = grounder.segment(observation(), LONG_PHRASE)
    assert detections
    assert_well_formed(detections, LONG_PHRASE)


def test_fit_phrase_drops_trailing_words_only_as_needed() -> None:
    tokenizer = tiny_tokenizer(64)
    assert fit_phrase(tokenizer, LONG_PHRASE, 64) == LONG_PHRASE
    assert fit_phrase(tokenizer, LONG_PHRASE, 2 + len("tallwoodenbookshelf")) == "tall wooden bookshelf"
    assert fit_phrase(tokenizer, LONG_PHRASE, 2 + len("tallwoodenbookshelf") - 1) == "tall wooden"
    assert fit_phrase(tokenizer, LONG_PHRASE, 3) == "tall"  # one word is always kept
