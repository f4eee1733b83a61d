"""The SAM3, OWLv2 and Grounding DINO grounders end to end on tiny randomly initialised transformers models (no
downloads).

The models and processors are :mod:`drivenav.semantics.random_grounders`' tiny configuration (``bench grounder --tiny``
uses the same): CLIP BPE tokenizers over a 55-entry letter vocabulary (a WordPiece one for Grounding DINO's BERT);
torchvision's fast image processors where torchvision is installed (those the grounders load), else OWLv2's and
Grounding DINO's PIL processors (injected: the grounders refuse to load them) and, for SAM3, a stand-in on ViT's PIL
backend.

The grounders split the forward into cached stages (text features per phrase, vision features per frame); the
equivalence tests compare them exactly with one plain forward of the model, in fp32 on the CPU.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("transformers")

import torch
from transformers import (
    GroundingDinoForObjectDetection,
    GroundingDinoProcessor,
    Owlv2ForObjectDetection,
    Owlv2Processor,
    Sam3Model,
    Sam3Processor,
)

from drivenav.errors import InputError
from drivenav.semantics.boxes import MAX_BOXES, FilledBoxSegmenter
from drivenav.semantics.grounding_dino_grounder import GroundingDinoGrounder
from drivenav.semantics.hf_common import fit_phrase, load_local, pick_device, ranked_detections, resolve_dtype
from drivenav.semantics.owlv2_grounder import Owlv2Grounder
from drivenav.semantics.protocols import Detection, Grounder
from drivenav.semantics.random_grounders import (
    HAS_TORCHVISION,
    TINY_GROUNDING_DINO_QUERIES,
    TINY_OWL_PATCH,
    TINY_OWL_SIZE,
    TINY_SAM3_QUERIES,
    letter_tokenizer,
    random_grounding_dino,
    random_owlv2,
    random_sam3,
)
from drivenav.semantics.sam3_grounder import Sam3Grounder
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose

H, W = 48, 64  # the frame; both models see a square image (56 pixels for SAM3, 64 for OWLv2)
OWL_BOXES = (TINY_OWL_SIZE // TINY_OWL_PATCH) ** 2  # one box per patch


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def sam3() -> tuple[Sam3Model, Sam3Processor]:
    torch.manual_seed(0)
    return random_sam3(tiny=True)


@pytest.fixture(scope="module")
def owl() -> tuple[Owlv2ForObjectDetection, Owlv2Processor]:
    """A tiny OWLv2 whose box regressor outputs zero, so each patch's box is its prior: centred on the patch's
    bottom-right corner, one patch wide (a random regressor saturates the sigmoid into degenerate boxes)."""
    torch.manual_seed(0)
    model, processor = random_owlv2(tiny=True)
    with torch.no_grad():
        model.box_head.dense2.weight.zero_()
        model.box_head.dense2.bias.zero_()
    return model, processor


@pytest.fixture(scope="module")
def gdino() -> tuple[GroundingDinoForObjectDetection, GroundingDinoProcessor]:
    torch.manual_seed(0)
    return random_grounding_dino(tiny=True)


def observation(seed: int = 0, step: int = 0) -> Observation:
    return Observation(
        rgb=np.random.default_rng(seed).integers(0, 256, (H, W, 3), dtype=np.uint8),
        depth=np.full((H, W), 2.0, np.float32),
        semantic=None,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(W, H, 79.0),
        step=step,
        collided=False,
    )


def sam3_grounder(sam3: tuple[Sam3Model, Sam3Processor], threshold: float) -> Sam3Grounder:
    model, processor = sam3
    return Sam3Grounder(device="cpu", score_threshold=threshold, model_obj=model, processor_obj=processor)


def owl_grounder(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor], threshold: float, **kwargs: Any) -> Owlv2Grounder:
    model, processor = owl
    return Owlv2Grounder(device="cpu", score_threshold=threshold, model_obj=model, processor_obj=processor, **kwargs)


def gdino_grounder(
    gdino: tuple[GroundingDinoForObjectDetection, GroundingDinoProcessor], threshold: float, **kwargs: Any
) -> GroundingDinoGrounder:
    model, processor = gdino
    return GroundingDinoGrounder(
        device="cpu", score_threshold=threshold, model_obj=model, processor_obj=processor, **kwargs
    )


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
    grounder.begin_episode(GroundTruth(labels={1: "chair"}), seed=3)


def test_sam3_threshold_zero_keeps_every_query_with_a_mask(sam3: tuple[Sam3Model, Sam3Processor]) -> None:
    detections = sam3_grounder(sam3, 0.0).segment(observation(), "red chair")
    assert 0 < len(detections) <= TINY_SAM3_QUERIES
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


@pytest.mark.skipif(not HAS_TORCHVISION, reason="SAM3's image processor is torchvision's only")
def test_sam3_loads_the_fast_processor_from_a_saved_directory(
    sam3: tuple[Sam3Model, Sam3Processor], tmp_path: Path
) -> None:
    sam3[0].save_pretrained(tmp_path)
    sam3[1].save_pretrained(tmp_path)
    loaded = Sam3Grounder(tmp_path, device="cpu", score_threshold=0.0)
    assert loaded.processor.image_processor.backend == "torchvision"
    assert exactly_equal(loaded.segment(observation(), "chair"), plain_sam3(sam3, observation(), "chair"))


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
        first_rows: np.ndarray = masks & (np.cumsum(masks, axis=1) == 1)
        return first_rows


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


@pytest.mark.skipif(not HAS_TORCHVISION, reason="loading takes torchvision's image processor")
def test_owlv2_loads_model_and_processor_from_a_saved_directory(
    owl: tuple[Owlv2ForObjectDetection, Owlv2Processor], tmp_path: Path
) -> None:
    model, processor = owl
    model.save_pretrained(tmp_path)
    processor.save_pretrained(tmp_path)
    loaded = Owlv2Grounder(str(tmp_path), device="cpu", score_threshold=0.0)
    assert loaded.model is not model and loaded.processor is not processor
    assert loaded.processor.image_processor.backend == "torchvision"
    assert same_detections(
        loaded.segment(observation(), "chair"), owl_grounder(owl, 0.0).segment(observation(), "chair")
    )


@pytest.mark.skipif(HAS_TORCHVISION, reason="checks the refusal without torchvision")
def test_owlv2_refuses_the_pil_image_processor(
    owl: tuple[Owlv2ForObjectDetection, Owlv2Processor], tmp_path: Path
) -> None:
    """transformers would fall back to the PIL processor (~300 ms a frame); the grounder says torchvision is
    missing instead (an ImportError, which the registry reports as the missing models extra)."""
    owl[0].save_pretrained(tmp_path)
    owl[1].save_pretrained(tmp_path)
    with pytest.raises(ImportError, match="torchvision"):
        Owlv2Grounder(str(tmp_path), device="cpu")


# --- Grounding DINO ---


def test_grounding_dino_satisfies_the_grounder_protocol(gdino: Any) -> None:
    grounder: Grounder = gdino_grounder(gdino, 0.35)
    assert grounder.name == "grounding-dino"
    grounder.begin_episode(None, seed=0)


def test_grounding_dino_scores_every_query_and_the_threshold_is_strict(gdino: Any) -> None:
    everything = gdino_grounder(gdino, 0.0).segment(observation(), "chair")
    assert 0 < len(everything) <= TINY_GROUNDING_DINO_QUERIES
    assert_well_formed(everything, "chair")
    scores = sorted({d.score for d in everything})
    cut = scores[len(scores) // 2]
    assert {d.score for d in gdino_grounder(gdino, cut).segment(observation(), "chair")} == {
        s for s in scores if s > cut
    }
    assert gdino_grounder(gdino, 1.0).segment(observation(), "chair") == []


def test_grounding_dino_uses_the_given_box_segmenter_on_the_best_boxes(gdino: Any) -> None:
    segmenter = TopRowSegmenter()
    detections = gdino_grounder(gdino, 0.0, segmenter=segmenter, max_boxes=3).segment(observation(), "chair")
    assert [call.shape for call in segmenter.calls] == [(3, 4)]
    assert all(bounding_rectangle(d.mask)[1] - bounding_rectangle(d.mask)[0] == 1 for d in detections)
    everything = gdino_grounder(gdino, 0.0).segment(observation(), "chair")
    assert [d.score for d in detections] == [d.score for d in everything[: len(detections)]]


def test_grounding_dino_prompt_is_the_lower_cased_phrase_with_a_period(gdino: Any) -> None:
    text = gdino_grounder(gdino, 0.0).encode_text("Red Chair")
    tokens = gdino[1].tokenizer.convert_ids_to_tokens(text.input_ids[0].tolist())
    assert tokens[0] == "[CLS]" and tokens[-2:] == [".", "[SEP]"] and "r" in tokens
    assert text.token_type_ids.shape == text.input_ids.shape
    assert text.encoded.shape[:2] == text.input_ids.shape  # the encoder's output, a token each


def test_grounding_dino_text_recorded_in_a_batch_serves_a_single_frame(gdino: Any) -> None:
    """The phrase's text encoder output, computed for a batch of three frames, is given back to a later single
    frame: the plain forward's detections, the encoder not run again."""
    grounder = gdino_grounder(gdino, 0.0)
    text_encoder, _ = encoders("grounding-dino", {"grounding-dino": gdino})
    with counting(text_encoder) as text_runs:
        grounder.segment_batch([observation(seed).rgb for seed in range(3)], "chair")
        single = grounder.segment(observation(5), "chair")
    assert len(text_runs) == 1
    assert exactly_equal(single, plain_boxes(gdino, observation(5), "chair"))


@pytest.mark.skipif(not HAS_TORCHVISION, reason="loading takes torchvision's image processor")
def test_grounding_dino_loads_model_and_processor_from_a_saved_directory(gdino: Any, tmp_path: Path) -> None:
    model, processor = gdino
    model.save_pretrained(tmp_path)
    processor.save_pretrained(tmp_path)
    loaded = GroundingDinoGrounder(str(tmp_path), device="cpu", score_threshold=0.0)
    assert loaded.model is not model and loaded.processor.image_processor.backend == "torchvision"
    assert same_detections(
        loaded.segment(observation(), "chair"), gdino_grounder(gdino, 0.0).segment(observation(), "chair")
    )


@pytest.mark.skipif(HAS_TORCHVISION, reason="checks the refusal without torchvision")
def test_grounding_dino_refuses_the_pil_image_processor(gdino: Any, tmp_path: Path) -> None:
    gdino[0].save_pretrained(tmp_path)
    gdino[1].save_pretrained(tmp_path)
    with pytest.raises(ImportError, match="torchvision"):
        GroundingDinoGrounder(str(tmp_path), device="cpu")


# --- missing weights, loading, device ---


@pytest.mark.parametrize("grounder", [Sam3Grounder, Owlv2Grounder, GroundingDinoGrounder])
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


WHICH = ["sam3", "owlv2", "grounding-dino"]
Models = dict[str, tuple[Any, Any]]


@pytest.fixture(scope="module")
def models(sam3: Any, owl: Any, gdino: Any) -> Models:
    return {"sam3": sam3, "owlv2": owl, "grounding-dino": gdino}


def fresh(which: str, models: Models) -> Sam3Grounder | Owlv2Grounder | GroundingDinoGrounder:
    """The grounder at threshold 0 (every query or box kept)."""
    if which == "sam3":
        return sam3_grounder(models["sam3"], 0.0)
    return owl_grounder(models["owlv2"], 0.0) if which == "owlv2" else gdino_grounder(models["grounding-dino"], 0.0)


LONG_PHRASE = "tall wooden bookshelf near the window"  # 37 characters: one token per letter here


@pytest.mark.parametrize("which", WHICH)
def test_a_phrase_longer_than_the_text_encoder_still_grounds(which: str, models: Models) -> None:
    grounder = fresh(which, models)
    detections = grounder.segment(observation(), LONG_PHRASE)
    assert detections
    assert_well_formed(detections, LONG_PHRASE)


def test_fit_phrase_drops_trailing_words_only_as_needed() -> None:
    tokenizer = letter_tokenizer(64)
    assert fit_phrase(tokenizer, LONG_PHRASE, 64) == LONG_PHRASE
    assert fit_phrase(tokenizer, LONG_PHRASE, 2 + len("tallwoodenbookshelf")) == "tall wooden bookshelf"
    assert fit_phrase(tokenizer, LONG_PHRASE, 2 + len("tallwoodenbookshelf") - 1) == "tall wooden"
    assert fit_phrase(tokenizer, LONG_PHRASE, 3) == "tall"  # one word is always kept


def test_fit_phrase_does_not_warn_of_the_length_it_fits() -> None:
    """The tokenizer's warning that a sequence is longer than the model's (transformers' logger, once a tokenizer)
    is not given while fitting: the phrase it measures is cut to fit before the model sees it."""
    told: list[str] = []
    listener = logging.Handler()
    listener.emit = lambda record: told.append(record.getMessage())  # type: ignore[method-assign]
    library = logging.getLogger("transformers")
    library.addHandler(listener)
    try:
        assert fit_phrase(letter_tokenizer(8), LONG_PHRASE, 8) == "tall"
        letter_tokenizer(8)(LONG_PHRASE)  # the warning this listener hears
    finally:
        library.removeHandler(listener)
    assert sum("longer than the specified maximum" in message for message in told) == 1  # the plain call's only


# --- the split, cached forward against one plain forward (fp32, CPU: exact) ---


@contextmanager
def counting(module: torch.nn.Module) -> Iterator[list[int]]:
    """How many times ``module`` runs forward inside the block."""
    calls: list[int] = []
    handle = module.register_forward_hook(lambda *_: calls.append(1))
    try:
        yield calls
    finally:
        handle.remove()


def plain_batch(processor: Any, rgb: np.ndarray, text: Any) -> Any:
    pixels = processor.image_processor([rgb], return_tensors="pt")["pixel_values"]
    return {**processor(text=text, return_tensors="pt"), "pixel_values": pixels}


def plain_sam3(sam3: tuple[Sam3Model, Sam3Processor], obs: Observation, phrase: str) -> list[Detection]:
    """What the grounder did before the split: one forward on the processor's image and text, then the
    processor's post-processing."""
    model, processor = sam3
    with torch.inference_mode():
        outputs = model(**plain_batch(processor, obs.rgb, phrase))
    result = processor.post_process_instance_segmentation(  # type: ignore[no-untyped-call]
        outputs, threshold=0.0, mask_threshold=0.5, target_sizes=[(H, W)]
    )[0]
    return ranked_detections(result["scores"].numpy(), result["masks"].bool().numpy(), phrase)


def plain_boxes(boxes_model: tuple[Any, Any], obs: Observation, phrase: str) -> list[Detection]:
    """OWLv2's or Grounding DINO's plain forward on the processor's image and phrase, the processor's boxes filled."""
    model, processor = boxes_model
    with torch.inference_mode():
        outputs = model(**plain_batch(processor, obs.rgb, [phrase]))
    result = processor.post_process_grounded_object_detection(outputs, threshold=0.0, target_sizes=[(H, W)])[0]
    masks = FilledBoxSegmenter().segment_boxes(obs.rgb, result["boxes"].numpy())
    return ranked_detections(result["scores"].numpy(), masks, phrase)


def exactly_equal(a: list[Detection], b: list[Detection]) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.mask, y.mask) and x.score == y.score and x.phrase == y.phrase
        for x, y in zip(a, b, strict=True)
    )


def encoders(which: str, models: Models) -> tuple[torch.nn.Module, torch.nn.Module]:
    """The text and vision encoders of the model (what the caches spare)."""
    model = models[which][0]
    if which == "sam3":
        return model.text_encoder, model.vision_encoder
    if which == "owlv2":
        return model.owlv2.text_model, model.owlv2.vision_model
    return model.model.text_backbone, model.model.backbone.conv_encoder


def plain(which: str, models: Models, obs: Observation, phrase: str) -> list[Detection]:
    return plain_sam3(models["sam3"], obs, phrase) if which == "sam3" else plain_boxes(models[which], obs, phrase)


PHRASES = ("chair", "red chair", "sofa", "potted plant", "tv")


@pytest.mark.parametrize("which", WHICH)
def test_split_forward_equals_the_plain_forward(which: str, models: Models) -> None:
    for seed, phrase in enumerate(PHRASES):
        obs = observation(seed)
        detections = fresh(which, models).segment(obs, phrase)
        assert detections and exactly_equal(detections, plain(which, models, obs, phrase))


@pytest.mark.parametrize("which", WHICH)
def test_several_phrases_on_one_frame_encode_it_once(which: str, models: Models) -> None:
    """Prompt enrichment's case: up to five phrases on the same frame; each answer is the plain forward's."""
    grounder, obs = fresh(which, models), observation(3, step=7)
    text_encoder, vision_encoder = encoders(which, models)
    with counting(vision_encoder) as vision_runs, counting(text_encoder) as text_runs:
        answers = [grounder.segment(obs, phrase) for phrase in PHRASES]
    assert (len(vision_runs), len(text_runs)) == (1, len(PHRASES))
    for phrase, detections in zip(PHRASES, answers, strict=True):
        assert exactly_equal(detections, plain(which, models, obs, phrase))


@pytest.mark.parametrize("which", WHICH)
def test_a_phrase_is_encoded_once_per_episode(which: str, models: Models) -> None:
    grounder = fresh(which, models)
    text_encoder, vision_encoder = encoders(which, models)
    grounder.begin_episode(None, seed=0)
    with counting(vision_encoder) as vision_runs, counting(text_encoder) as text_runs:
        answers = [grounder.segment(observation(seed, step=seed), "chair") for seed in range(3)]
        assert (len(vision_runs), len(text_runs)) == (3, 1)
        grounder.begin_episode(None, seed=1)  # a new episode encodes its phrases again
        grounder.segment(observation(0, step=0), "chair")
        assert (len(vision_runs), len(text_runs)) == (4, 2)
    for seed, detections in enumerate(answers):
        assert exactly_equal(detections, plain(which, models, observation(seed), "chair"))


@pytest.mark.parametrize("which", WHICH)
def test_a_new_frame_is_encoded_even_at_the_same_step(which: str, models: Models) -> None:
    """The frame cache compares pixels, not only the step: a world that reuses its image buffer gets no stale
    features."""
    grounder = fresh(which, models)
    _, vision_encoder = encoders(which, models)
    first, second = observation(0, step=4), observation(1, step=4)
    with counting(vision_encoder) as vision_runs:
        grounder.segment(first, "chair")
        first.rgb[:] = second.rgb  # the same array, new pixels
        in_place = grounder.segment(first, "chair")
        grounder.segment(observation(1, step=5), "chair")  # same pixels, next step
    assert len(vision_runs) == 3
    assert exactly_equal(in_place, plain(which, models, second, "chair"))


@pytest.mark.parametrize("which", WHICH)
def test_a_batch_of_frames_gives_each_frame_its_detections(which: str, models: Models) -> None:
    """One forward over several frames (the bench's ``--batch``): per frame, the single-frame answer (a batched
    matrix product may round differently, so scores within 1e-6)."""
    frames = [observation(seed) for seed in range(3)]
    batched = fresh(which, models).segment_batch([f.rgb for f in frames], "chair")
    assert len(batched) == 3
    for frame, detections in zip(frames, batched, strict=True):
        assert same_detections(detections, plain(which, models, frame, "chair"))


@pytest.mark.parametrize("which", WHICH)
def test_rows_of_different_phrases_share_one_forward_and_their_frames_encoding(which: str, models: Models) -> None:
    """A server's batch (``segment_rows``): two frames, five rows each with its own phrase, one frame read by
    three rows. The vision encoder runs once over the two frames; each row's detections are its phrase's in its
    frame alone, the plain forward's (Grounding DINO pads the shorter prompts: scores within a batched product's
    rounding)."""
    grounder = fresh(which, models)
    frames = [observation(seed) for seed in (4, 6)]
    rows = [(0, "chair"), (1, "potted plant"), (0, "tv"), (1, "chair"), (0, "red chair")]
    _, vision_encoder = encoders(which, models)
    with counting(vision_encoder) as vision_runs:
        found = grounder.segment_rows(grounder.preprocess([f.rgb for f in frames]), [f.rgb for f in frames], rows)
    assert len(vision_runs) == 1 and len(found) == len(rows)
    for (index, phrase), detections in zip(rows, found, strict=True):
        assert detections and {d.phrase for d in detections} == {phrase}
        assert same_detections(detections, plain(which, models, frames[index], phrase))


def test_owlv2_masks_only_the_best_boxes(owl: tuple[Owlv2ForObjectDetection, Owlv2Processor]) -> None:
    """At threshold 0 all 64 boxes pass; with ``max_boxes=5`` the segmenter sees only the 5 best, and the answer is
    the first 5 of the full one."""
    segmenter = TopRowSegmenter()
    everything = owl_grounder(owl, 0.0, segmenter=TopRowSegmenter()).segment(observation(), "chair")
    best = owl_grounder(owl, 0.0, segmenter=segmenter, max_boxes=5).segment(observation(), "chair")
    assert [call.shape for call in segmenter.calls] == [(5, 4)]
    assert exactly_equal(best, everything[:5])
    assert MAX_BOXES == 100


# --- dtype ---


def test_dtype_auto_is_fp32_on_the_cpu_and_names_are_torch_dtypes() -> None:
    assert resolve_dtype("auto", "cpu") == torch.float32
    assert resolve_dtype("float32", "cpu") == torch.float32
    assert resolve_dtype("bfloat16", "cpu") == torch.bfloat16
    assert resolve_dtype("float16", "cuda") == torch.float16
    if torch.cuda.is_available():
        expected = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float32
        assert resolve_dtype("auto", "cuda:0") == expected


@pytest.mark.parametrize("which", WHICH)
def test_bfloat16_casts_the_model_and_still_grounds(which: str, models: Models) -> None:
    """The model is cast (a copy here: the fixtures stay fp32) and the pixels follow; detections stay well formed
    and the text features are bf16 too."""
    model, processor = copy.deepcopy(models[which])
    kind = {"sam3": Sam3Grounder, "owlv2": Owlv2Grounder, "grounding-dino": GroundingDinoGrounder}[which]
    grounder = kind(device="cpu", score_threshold=0.0, dtype="bfloat16", model_obj=model, processor_obj=processor)
    assert grounder.model.dtype == torch.bfloat16
    assert grounder.preprocess([observation().rgb]).dtype == torch.bfloat16
    assert_well_formed(grounder.segment(observation(), "chair"), "chair")


@pytest.mark.parametrize(("detector", "segmenter"), [("sam3", "filled-box"), ("grounding-dino", "mobilesam")])
def test_the_random_weights_of_a_bench_or_server_are_the_same_every_time(detector: str, segmenter: str) -> None:
    """Two random grounders of one spec (two runs of a bench, or a server's two copies) hold the same weights, their
    MobileSAM too, and building them leaves torch's own generator as it was."""
    from drivenav.semantics.model_spec import ModelSpec
    from drivenav.semantics.random_grounders import random_grounder

    spec = ModelSpec(detector=detector, segmenter=segmenter, detector_device="cpu")
    before = torch.get_rng_state()
    first, second = (random_grounder(spec, tiny=True) for _ in range(2))
    assert torch.equal(torch.get_rng_state(), before)
    modules = [(first.model, second.model)]
    if segmenter == "mobilesam":
        modules.append((first.segmenter.model, second.segmenter.model))  # type: ignore[attr-defined]
    for one, other in modules:
        weights, again = one.state_dict(), other.state_dict()
        assert weights.keys() == again.keys()
        assert all(torch.equal(weights[name], again[name]) for name in weights)
