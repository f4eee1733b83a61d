"""The image-text scorers of the VLFM baseline: the embedded stand-in, and BLIP-2 ITM and SigLIP on tiny randomly
initialised transformers models (no downloads), checked against the same similarity computed another way."""

from __future__ import annotations

import importlib.util
import math
import string
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from drivenav.doctor import scorer_check
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError
from drivenav.semantics.embedded import EmbeddedReasonerConfig
from drivenav.semantics.embedded_scorer import EmbeddedScorer
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import ImageTextScorer
from drivenav.semantics.registry import check_models, make_scorer
from drivenav.types import GroundTruth
from frames import observation_of

HAS_MODELS = all(importlib.util.find_spec(name) is not None for name in ("torch", "transformers"))
needs_models = pytest.mark.skipif(not HAS_MODELS, reason="the models extra (torch, transformers) is not installed")

# --- the embedded stand-in ---

H, W = 480, 640
LABELS = {1: "sofa", 2: "couch", 3: "lamp", 4: "toilet", 5: "armchair"}
TRUTH = GroundTruth(LABELS, VOCABULARY)
CONFIG = EmbeddedReasonerConfig()


def semantic(*boxes: tuple[int, int, int, int, int]) -> NDArray[np.int32]:
    """An instance image: each box (instance, row0, row1, col0, col1) painted over the background 0."""
    image = np.zeros((H, W), dtype=np.int32)
    for instance, r0, r1, c0, c1 in boxes:
        image[r0:r1, c0:c1] = instance
    return image


def embedded() -> EmbeddedScorer:
    scorer = EmbeddedScorer(default_embedder())
    scorer.begin_episode(TRUTH)
    return scorer


def by_hand(related: float, pixels: int) -> float:
    """The embedded reasoner's semantic term of one label, written out: ramp(r) * area_weight(share)."""
    ramp = min(max((related - 0.3) / 0.7, 0.0), 1.0)
    share = pixels / (H * W)
    return ramp * (0.5 + 0.5 * share / (share + 0.02))


RGB = np.zeros((H, W, 3), dtype=np.uint8)
BIG, SMALL = (0, 200, 0, 300), (0, 20, 0, 20)  # 60,000 and 400 pixels


def test_embedded_satisfies_the_protocol_and_counts_its_calls() -> None:
    scorer: ImageTextScorer = embedded()
    assert scorer.name == "embedded"
    scorer.score("sofa", observation_of(RGB, semantic((1, *BIG))))
    scorer.score("sofa", observation_of(RGB))
    assert [(c.kind, c.outcome) for c in scorer.calls] == [("score", "ok")] * 2
    assert all(c.latency_ms >= 0.0 for c in scorer.calls)
    scorer.begin_episode(TRUTH)
    assert scorer.calls == []


def test_the_goal_scores_by_its_area_as_the_reasoner_weighs_it() -> None:
    scorer = embedded()
    assert scorer.score("sofa", observation_of(RGB, semantic((1, *BIG)))) == pytest.approx(
        by_hand(1.0, 60_000), abs=1e-12
    )
    assert scorer.score("sofa", observation_of(RGB, semantic((1, *SMALL)))) == pytest.approx(
        by_hand(1.0, 400), abs=1e-12
    )
    assert by_hand(1.0, 400) == pytest.approx(0.5 + 0.5 * (400 / 307_200) / (400 / 307_200 + 0.02))
    assert scorer.score("couch", observation_of(RGB, semantic((1, *BIG)))) == scorer.score(
        "sofa", observation_of(RGB, semantic((1, *BIG)))
    )


def test_the_goal_beats_related_and_unrelated_things_of_the_same_area() -> None:
    scorer = embedded()
    goal, related, unrelated = (scorer.score("sofa", observation_of(RGB, semantic((i, *BIG)))) for i in (2, 5, 4))
    similarity = default_embedder().similarity("armchair", "sofa")
    assert related == pytest.approx(by_hand(similarity, 60_000), abs=1e-6)
    assert goal > related > unrelated >= 0.0 and goal < 1.0


def test_the_best_visible_label_counts_and_glimpses_are_ignored() -> None:
    scorer = embedded()
    both = semantic((4, *BIG), (1, 300, 320, 0, 20))  # the sofa seen beside a large toilet
    assert scorer.score("sofa", observation_of(RGB, both)) == scorer.score(
        "sofa", observation_of(RGB, semantic((1, 300, 320, 0, 20)))
    )
    glimpse = semantic((1, 0, 10, 0, 14))  # 140 pixels < min_pixels 150
    assert scorer.score("sofa", observation_of(RGB, glimpse)) == 0.0


def test_without_semantics_or_ground_truth_the_score_is_neutral() -> None:
    scorer = embedded()
    assert scorer.score("sofa", observation_of(RGB)) == 0.0
    assert scorer.score("sofa", observation_of(RGB, semantic())) == 0.0
    blind = EmbeddedScorer(default_embedder())
    blind.begin_episode(None)
    assert blind.score("sofa", observation_of(RGB, semantic((1, *BIG)))) == 0.0


def test_rgb_is_not_read() -> None:
    scorer = embedded()
    noise = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    assert scorer.score("sofa", observation_of(noise, semantic((1, *BIG)))) == scorer.score(
        "sofa", observation_of(RGB, semantic((1, *BIG)))
    )


# --- BLIP-2 ITM and SigLIP (tiny random models) ---

FH, FW = 48, 64  # the frame; the models see IMAGE x IMAGE pixels
IMAGE, PATCH = 32, 8
VISION = {"hidden_size": 32, "intermediate_size": 64, "num_hidden_layers": 1, "num_attention_heads": 2}
QUERIES = 4
TEXT_TOKENS = 64  # SigLIP's text length: the prompt (a token a letter here) fits, as with the real tokenizer


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread() -> Iterator[None]:
    """Tiny models gain nothing from threads; on shared cores extra threads only oversubscribe them."""
    if not HAS_MODELS:
        yield
        return
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def frame(seed: int = 0) -> NDArray[np.uint8]:
    return np.random.default_rng(seed).integers(0, 256, (FH, FW, 3), dtype=np.uint8)


def transformers() -> Any:
    """The transformers module, untyped (its constructors carry no annotations)."""
    return importlib.import_module("transformers")


def bert_tokenizer() -> Any:
    """WordPiece over single letters: every word is its first letter then ``##`` continuations."""
    letters = list(string.ascii_lowercase)
    vocab = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", *letters, *(f"##{c}" for c in letters)]
    return transformers().BertTokenizer(vocab={token: i for i, token in enumerate(vocab)})


def blip2_config() -> Any:
    qformer = {
        "vocab_size": 64,
        "hidden_size": 32,
        "num_hidden_layers": 2,
        "num_attention_heads": 2,
        "intermediate_size": 64,
        "encoder_hidden_size": 32,
        "max_position_embeddings": 40,
        "cross_attention_frequency": 1,
        "use_qformer_text_input": True,
    }
    vision = {**VISION, "image_size": IMAGE, "patch_size": PATCH}
    return transformers().Blip2Config(
        vision_config=vision, qformer_config=qformer, num_query_tokens=QUERIES, image_text_hidden_size=16
    )


@pytest.fixture(scope="module")
def blip2() -> tuple[Any, Any]:
    import torch

    hf = transformers()
    torch.manual_seed(0)
    image_processor = hf.BlipImageProcessorPil(size={"height": IMAGE, "width": IMAGE})
    processor = hf.Blip2Processor(image_processor=image_processor, tokenizer=bert_tokenizer())
    return hf.Blip2ForImageTextRetrieval(blip2_config()).eval(), processor


@pytest.fixture(scope="module")
def siglip() -> tuple[Any, Any]:
    """A tiny SigLIP with a temperature of 10 and a bias of -2, so that both must be applied."""
    import torch

    from drivenav.semantics.random_grounders import letter_tokenizer as tiny_tokenizer

    hf = transformers()
    torch.manual_seed(0)
    text = {**VISION, "vocab_size": 64, "max_position_embeddings": TEXT_TOKENS, "bos_token_id": 1, "eos_token_id": 2}
    config = hf.SiglipConfig(text_config=text, vision_config={**VISION, "image_size": IMAGE, "patch_size": PATCH})
    model = hf.SiglipModel(config).eval()
    with torch.no_grad():
        model.logit_scale.fill_(math.log(10.0))
        model.logit_bias.fill_(-2.0)
    image_processor = hf.SiglipImageProcessorPil(size={"height": IMAGE, "width": IMAGE})
    return model, hf.SiglipProcessor(image_processor=image_processor, tokenizer=tiny_tokenizer(TEXT_TOKENS))


def blip2_scorer(blip2: tuple[Any, Any]) -> Any:
    from drivenav.semantics.itm_scorer import Blip2ItmScorer

    return Blip2ItmScorer(device="cpu", model_obj=blip2[0], processor_obj=blip2[1])


def siglip_scorer(siglip: tuple[Any, Any]) -> Any:
    from drivenav.semantics.itm_scorer import SiglipScorer

    return SiglipScorer(device="cpu", model_obj=siglip[0], processor_obj=siglip[1])


def test_the_prompt_is_vlfms_and_blip_cleans_it_as_lavis_does() -> None:
    from drivenav.semantics.itm_scorer import VLFM_PROMPT, blip_caption

    assert VLFM_PROMPT.format(target="chair") == "Seems like there is a chair ahead."
    assert blip_caption(VLFM_PROMPT.format(target="TV (wall)")) == "seems like there is a tv wall ahead"
    assert blip_caption('  a "b"!  c;d~  ') == "a b c d"


@needs_models
def test_blip2_scores_the_itc_cosine_maximised_over_queries(blip2: tuple[Any, Any]) -> None:
    """The same cosine through the separate vision and text towers (their weights are the retrieval model's)."""
    import torch
    from PIL import Image

    hf = transformers()
    model, processor = blip2
    towers = [hf.Blip2VisionModelWithProjection(blip2_config()), hf.Blip2TextModelWithProjection(blip2_config())]
    for tower in towers:
        assert tower.load_state_dict(model.state_dict(), strict=False).missing_keys == []
        tower.eval()
    pixels = processor.image_processor(images=Image.fromarray(frame()), return_tensors="pt")["pixel_values"]
    tokens = processor.tokenizer("seems like there is a chair ahead", return_tensors="pt")
    with torch.no_grad():
        image = towers[0](pixel_values=pixels).image_embeds[0]  # (queries, dim)
        text = towers[1](input_ids=tokens["input_ids"], attention_mask=tokens["attention_mask"]).text_embeds[0, 0]
    cosines = torch.nn.functional.normalize(image, dim=-1) @ torch.nn.functional.normalize(text, dim=-1)
    assert cosines.shape == (QUERIES,)

    scorer: ImageTextScorer = blip2_scorer(blip2)
    assert scorer.name == "blip2-itm"
    value = scorer.score("Chair", observation_of(frame()))
    assert value == pytest.approx(float(cosines.max()), abs=1e-5)
    assert -1.0 <= value <= 1.0 and isinstance(value, float)
    assert scorer.score("chair", observation_of(frame())) == pytest.approx(value, abs=1e-6)  # lower case anyway
    assert scorer.score("sofa", observation_of(frame())) != pytest.approx(value, abs=1e-6)
    assert [(c.kind, c.outcome) for c in scorer.calls] == [("score", "ok")] * 3


@needs_models
def test_blip2_never_prepends_image_tokens_to_the_text(blip2: tuple[Any, Any]) -> None:
    """A processor saved for BLIP-2's language models (num_query_tokens set) still scores the plain text."""
    from drivenav.semantics.itm_scorer import Blip2ItmScorer

    model, processor = blip2
    llm_processor = transformers().Blip2Processor(processor.image_processor, bert_tokenizer(), num_query_tokens=QUERIES)
    with_tokens = Blip2ItmScorer(device="cpu", model_obj=model, processor_obj=llm_processor)
    assert with_tokens.score("chair", observation_of(frame())) == pytest.approx(
        blip2_scorer(blip2).score("chair", observation_of(frame()))
    )


@needs_models
def test_siglip_scores_the_sigmoid_of_the_scaled_biased_cosine(siglip: tuple[Any, Any]) -> None:
    import torch
    from PIL import Image

    model, processor = siglip
    text = "Seems like there is a chair ahead."
    batch = processor(images=Image.fromarray(frame()), text=[text], padding="max_length", return_tensors="pt")
    assert batch["input_ids"].shape == (1, TEXT_TOKENS)  # padded to the text encoder's length
    with torch.no_grad():
        image = model.get_image_features(pixel_values=batch["pixel_values"]).pooler_output[0]
        words = model.get_text_features(input_ids=batch["input_ids"]).pooler_output[0]
    cosine = float(torch.nn.functional.cosine_similarity(image, words, dim=0))
    expected = 1.0 / (1.0 + math.exp(-(10.0 * cosine - 2.0)))

    scorer: ImageTextScorer = siglip_scorer(siglip)
    assert scorer.name == "siglip"
    value = scorer.score("chair", observation_of(frame()))
    assert value == pytest.approx(expected, abs=1e-5) and 0.0 < value < 1.0
    assert scorer.score("chair", observation_of(frame(1))) != pytest.approx(value, abs=1e-6)
    assert [(c.kind, c.outcome) for c in scorer.calls] == [("score", "ok")] * 2
    scorer.begin_episode(None)
    assert scorer.calls == []


@needs_models
def test_a_non_finite_similarity_is_a_neutral_fallback(siglip: tuple[Any, Any]) -> None:
    import copy

    import torch

    broken = copy.deepcopy(siglip[0])
    with torch.no_grad():
        broken.logit_bias.fill_(math.nan)
    from drivenav.semantics.itm_scorer import SiglipScorer

    scorer = SiglipScorer(device="cpu", model_obj=broken, processor_obj=siglip[1])
    assert scorer.score("chair", observation_of(frame())) == 0.0
    assert [(c.kind, c.outcome) for c in scorer.calls] == [("score", "fallback")]


@pytest.fixture(scope="module")
def saved(blip2: tuple[Any, Any], siglip: tuple[Any, Any], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both tiny checkpoints written with ``save_pretrained``, model and processor, as a user's directory."""
    folders = {}
    for name, (model, processor) in (("blip2-itm", blip2), ("siglip", siglip)):
        folder = tmp_path_factory.mktemp(name)
        model.save_pretrained(folder)
        processor.save_pretrained(folder)
        folders[name] = folder
    return folders


@needs_models
@pytest.mark.parametrize("name", ["blip2-itm", "siglip"])
def test_the_registry_loads_a_saved_checkpoint(
    name: str, saved: dict[str, Path], blip2: tuple[Any, Any], siglip: tuple[Any, Any]
) -> None:
    spec = ModelSpec(scorer=name, scorer_model=str(saved[name]))
    check_models(spec)  # loads the weights before any episode
    scorer = make_scorer(spec)
    assert scorer.name == name
    given = blip2_scorer(blip2) if name == "blip2-itm" else siglip_scorer(siglip)
    assert scorer.score("chair", observation_of(frame())) == pytest.approx(
        given.score("chair", observation_of(frame())), abs=1e-6
    )


@needs_models
@pytest.mark.parametrize("name", ["blip2-itm", "siglip"])
def test_missing_weights_are_a_one_line_error_naming_the_scorer_model(name: str, tmp_path: Path) -> None:
    with pytest.raises(InputError) as caught:
        check_models(ModelSpec(scorer=name, scorer_model=str(tmp_path / "nowhere")))
    message = str(caught.value)
    assert "\n" not in message and message.startswith("command line: field '--scorer-model': expected a local ")
    assert str(tmp_path / "nowhere")[:40] in message


@pytest.mark.parametrize("name", ["blip2-itm", "siglip"])
def test_without_the_models_extra_the_scorer_names_it(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "transformers", None)  # as if the extra were not installed
    with pytest.raises(InputError) as caught:
        check_models(ModelSpec(scorer=name))
    message = str(caught.value)
    assert "field '--scorer'" in message and f"models extra for {name}" in message
    assert "pip install 'drivenav[models]'" in message and "transformers not installed" in message


@needs_models
def test_doctor_loads_the_scorer_and_scores_one_frame(saved: dict[str, Path], tmp_path: Path) -> None:
    check = scorer_check(ModelSpec(scorer="siglip", scorer_model=str(saved["siglip"])))
    assert check.ok and check.name == "scorer siglip" and "one frame in" in check.detail and "score 0." in check.detail
    failed = scorer_check(ModelSpec(scorer="blip2-itm", scorer_model=str(tmp_path / "nowhere")))
    assert not failed.ok and "--scorer-model" in failed.detail and "--scorer-model" in failed.fix
