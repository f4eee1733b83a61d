"""``models.compile`` (``--compile``): ``torch.compile`` of the modules every frame runs through, on tiny random
models on the CPU.

Inductor, the backend ``--compile`` uses, generates and builds C++ for every kernel on a CPU: on the project's 2-core
machines it takes minutes for even the tiny OWLv2 with MobileSAM (224 s measured), so the whole-grounder check runs
on ``aot_eager``, which traces the same graphs through TorchDynamo and AOTAutograd and runs them with eager kernels
(what a compile-time failure or a graph that computes something else would show), and one real inductor check
compiles a small module of a real model. Which modules are compiled is checked for every grounder: those each new
frame runs through, never the text encoders (run once per phrase and episode).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("transformers")

import torch

from drivenav.semantics.grounding_dino_grounder import GroundingDinoGrounder
from drivenav.semantics.hf_common import COMPILE_BACKEND, TransformersGrounder, compile_backend_for, compile_modules
from drivenav.semantics.mobilesam_segmenter import MobileSamSegmenter
from drivenav.semantics.owlv2_grounder import Owlv2Grounder
from drivenav.semantics.random_grounders import RANDOM_DETECTORS, random_mobile_sam, random_owlv2
from drivenav.semantics.sam3_grounder import Sam3Grounder
from drivenav.types import CameraIntrinsics, Observation, Pose

H, W = 48, 64


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def observation(seed: int, step: int) -> Observation:
    rgb = np.random.default_rng(seed).integers(0, 256, (H, W, 3), dtype=np.uint8)
    depth = np.full((H, W), 2.0, np.float32)
    return Observation(rgb, depth, None, Pose(0.0, 0.0, 0.0), CameraIntrinsics.from_hfov(W, H, 79.0), step, False)


def owl_with_mobile_sam(compile_backend: str) -> Owlv2Grounder:
    """The tiny OWLv2 (boxes at their patch priors) with the tiny MobileSAM, both compiled on ``compile_backend``."""
    torch.manual_seed(0)
    model, processor = random_owlv2(tiny=True)
    with torch.no_grad():
        model.box_head.dense2.weight.zero_()
        model.box_head.dense2.bias.zero_()
    segmenter = MobileSamSegmenter(random_mobile_sam(tiny=True), "cpu", compile_backend=compile_backend)
    return Owlv2Grounder(
        device="cpu",
        score_threshold=0.0,
        max_boxes=8,
        model_obj=model,
        processor_obj=processor,
        segmenter=segmenter,
        compile_backend=compile_backend,
    )


def test_a_compiled_grounder_gives_the_eager_detections() -> None:
    """OWLv2 with MobileSAM traced and compiled (``aot_eager``), over two frames and two phrases: the eager
    grounder's detections (scores within float rounding, masks equal)."""
    eager, compiled = owl_with_mobile_sam(""), owl_with_mobile_sam("aot_eager")
    found = 0
    for step, phrase in ((0, "chair"), (0, "red sofa"), (1, "chair")):
        expected = eager.segment(observation(step, step), phrase)
        got = compiled.segment(observation(step, step), phrase)
        assert len(got) == len(expected) > 0
        for a, b in zip(got, expected, strict=True):
            assert a.score == pytest.approx(b.score, abs=1e-5) and np.array_equal(a.mask, b.mask)
        found += len(got)
    assert found > 0


def test_inductor_compiles_a_model_module_to_its_eager_outputs() -> None:
    """The backend ``--compile`` uses, for real: the tiny OWLv2's box head (three linear layers) through
    :func:`compile_modules`."""
    model, _ = random_owlv2(tiny=True)
    head = copy.deepcopy(model.box_head).eval()
    features = torch.randn(2, 64, head.dense0.in_features)
    with torch.inference_mode():
        expected = head(features)
        compile_modules([head], COMPILE_BACKEND)
        assert torch.allclose(head(features), expected, atol=1e-5)


def test_compile_is_off_unless_asked() -> None:
    assert compile_backend_for(False) == "" and compile_backend_for(True) == COMPILE_BACKEND == "inductor"
    module = torch.nn.Linear(2, 2)
    compile_modules([module], "")
    assert module._compiled_call_impl is None


GROUNDERS = {"sam3": Sam3Grounder, "owlv2": Owlv2Grounder, "grounding-dino": GroundingDinoGrounder}


def built(which: str) -> TransformersGrounder:
    torch.manual_seed(0)
    model, processor = RANDOM_DETECTORS[which](True, "cpu")
    grounder: TransformersGrounder = GROUNDERS[which](device="cpu", model_obj=model, processor_obj=processor)
    return grounder


def text_encoder(which: str, model: Any) -> torch.nn.Module:
    encoders = {
        "sam3": lambda: model.text_encoder,
        "owlv2": lambda: model.owlv2.text_model,
        "grounding-dino": lambda: model.model.text_backbone,
    }
    module: torch.nn.Module = encoders[which]()
    return module


@pytest.mark.parametrize("which", ["sam3", "owlv2", "grounding-dino"])
def test_the_compiled_modules_are_those_every_new_frame_runs(which: str) -> None:
    """A new frame with a phrase already seen runs each compiled module (and so runs compiled); the text encoder,
    run once per phrase, is not compiled."""
    grounder = built(which)
    modules = grounder.compiled_modules()
    assert modules and all(isinstance(m, torch.nn.Module) for m in modules)
    assert all(text_encoder(which, grounder.model) is not m for m in modules)
    grounder.segment(observation(0, 0), "chair")
    runs = [0] * len(modules)
    handles = [m.register_forward_hook(lambda *_, k=k: runs.__setitem__(k, runs[k] + 1)) for k, m in enumerate(modules)]
    try:
        grounder.segment(observation(1, 1), "chair")
    finally:
        for handle in handles:
            handle.remove()
    assert all(count >= 1 for count in runs), runs


def test_mobile_sam_compiles_its_encoder_and_decoder() -> None:
    segmenter = MobileSamSegmenter(random_mobile_sam(tiny=True), "cpu", compile_backend="aot_eager")
    compiled = [m for m in segmenter.model.modules() if getattr(m, "_compiled_call_impl", None) is not None]
    assert compiled == [segmenter.model.image_encoder, segmenter.model.mask_decoder]
