"""MobileSAM as the box segmenter (``--segmenter mobilesam``) on tiny random models: masks inside their boxes on a
drawn shape, the frame-to-input geometry against a decoder that answers with its prompt, the package's own ``Sam``
forward as the reference, checkpoints (drivenav's file and the released ``vit_t`` state dict of the package's own
builder), dtype and the one-line errors.

``mobile_sam``'s TinyViT imports timm, which the dev venv lacks (timm needs torchvision): where it is absent, the
tests that build ``vit_t`` put a stand-in for its four helpers in place (tests/timm_stand_in.py).
"""

from __future__ import annotations

import copy
import importlib
import importlib.util
import sys
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch")
if importlib.util.find_spec("mobile_sam") is None:
    pytest.skip("mobilesam-mirror is not installed (the models and dev extras)", allow_module_level=True)

import torch

from drivenav.errors import InputError
from drivenav.semantics.boxes import FilledBoxSegmenter
from drivenav.semantics.mobilesam_segmenter import (
    PIXEL_MEAN,
    PIXEL_STD,
    TINY_SIZE,
    MobileSamModel,
    MobileSamSegmenter,
    build_architecture,
    load_checkpoint,
    model_code,
    save_checkpoint,
)
from timm_stand_in import install as install_timm_stand_in

H, W = 30, 40  # the frame: its long side is resized to the tiny encoder's 64 pixels (x 1.6), 48 x 64 then padded


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def tiny() -> MobileSamModel:
    torch.manual_seed(0)
    return build_architecture("tiny").eval()


def segmenter(model: MobileSamModel, **kwargs: Any) -> MobileSamSegmenter:
    return MobileSamSegmenter(copy.deepcopy(model), "cpu", **kwargs)


def disc_frame() -> np.ndarray:
    """A red disc of radius 8 centred at (row 14, column 18) on grey noise."""
    rng = np.random.default_rng(0)
    rgb = rng.integers(100, 140, (H, W, 3), dtype=np.uint8)
    rows, cols = np.mgrid[:H, :W]
    rgb[(rows - 14) ** 2 + (cols - 18) ** 2 <= 64] = (220, 30, 30)
    return rgb


BOXES = np.array(
    [
        [10.0, 6.0, 27.0, 23.0],  # around the disc
        [18.0, 14.0, 27.0, 23.0],  # its lower-right quarter
        [-8.0, 20.0, 52.0, 45.0],  # reaching past three edges of the frame
        [5.2, 5.0, 5.4, 25.0],  # narrower than a pixel: no pixel centre inside
    ],
    dtype=np.float32,
)


def test_masks_lie_inside_their_boxes_on_a_drawn_shape(tiny: MobileSamModel) -> None:
    masks = segmenter(tiny).segment_boxes(disc_frame(), BOXES)
    assert masks.shape == (len(BOXES), H, W) and masks.dtype == np.bool_
    boxes = FilledBoxSegmenter().segment_boxes(disc_frame(), BOXES)
    assert not (masks & ~boxes).any()
    assert masks[:3].any(axis=(1, 2)).all()  # random weights still mark pixels in every real box
    assert not masks[3].any()
    assert (masks[0] != boxes[0]).any()  # a mask, not the filled box


def test_each_box_is_segmented_as_if_alone(tiny: MobileSamModel) -> None:
    """The decoder treats boxes independently: a box's mask is the same in a batch and alone (logits within a
    batched product's rounding, so a pixel on the threshold may differ)."""
    model = segmenter(tiny)
    together = model.segment_boxes(disc_frame(), BOXES)
    for k in range(len(BOXES)):
        alone = model.segment_boxes(disc_frame(), BOXES[k : k + 1])[0]
        assert (alone != together[k]).sum() <= 2


def test_no_boxes_costs_no_forward(tiny: MobileSamModel) -> None:
    model = segmenter(tiny)
    calls: list[int] = []
    model.model.image_encoder.register_forward_hook(lambda *_: calls.append(1))
    masks = model.segment_boxes(disc_frame(), np.zeros((0, 4), np.float32))
    assert masks.shape == (0, H, W) and calls == []
    model.segment_boxes(disc_frame(), BOXES[:1])
    assert calls == [1]


class PromptPainter(torch.nn.Module):
    """A mask decoder that answers each box prompt with the box itself: +1 on the low-resolution cells whose centres
    lie inside the box (in the padded input's pixels), -1 elsewhere; the boxes come from the prompt encoder."""

    def __init__(self, prompts: list[torch.Tensor], size: int, cells: int) -> None:
        super().__init__()
        self.prompts, self.size, self.cells = prompts, size, cells

    def forward(self, **kwargs: Any) -> tuple[torch.Tensor, torch.Tensor]:
        boxes = self.prompts[-1]
        centres = (torch.arange(self.cells) + 0.5) * self.size / self.cells
        inside_x = (centres >= boxes[:, 0, None]) & (centres < boxes[:, 2, None])
        inside_y = (centres >= boxes[:, 1, None]) & (centres < boxes[:, 3, None])
        painted = inside_y[:, :, None] & inside_x[:, None, :]
        return (painted.float() * 2 - 1)[:, None], torch.ones(len(boxes), 1)


def test_the_frame_and_its_boxes_map_to_the_input_and_back(tiny: MobileSamModel) -> None:
    """With a decoder that paints its box prompt, each mask is its box in frame pixels, up to the boundary band that
    bilinear upsampling of 4-pixel cells blurs (1.6 input pixels per frame pixel): boxes scaled like the frame,
    the padding cropped before the resize to the frame."""
    model = segmenter(tiny)
    prompts: list[torch.Tensor] = []
    model.model.prompt_encoder.register_forward_pre_hook(
        lambda _, args, kwargs: prompts.append(kwargs["boxes"]), with_kwargs=True
    )
    model.model.mask_decoder = PromptPainter(prompts, TINY_SIZE, TINY_SIZE // 4)
    boxes = np.array([[4.0, 3.0, 30.0, 21.0], [20.0, 10.0, 40.0, 30.0]], np.float32)
    masks = model.segment_boxes(disc_frame(), boxes)
    assert torch.allclose(prompts[-1], torch.from_numpy(boxes) * 1.6)
    filled = FilledBoxSegmenter().segment_boxes(disc_frame(), boxes)
    for mask, box, expected in zip(masks, boxes, filled, strict=True):
        rows, cols = np.mgrid[:H, :W] + 0.5
        depth = np.minimum.reduce([cols - box[0], rows - box[1], box[2] - cols, box[3] - rows])
        assert mask[depth >= 2.0].all()  # the box's inner part
        assert (mask == expected)[np.abs(depth) >= 2.0].all()  # and only the boundary band differs


# --- the package's own model as the reference --------------------------------------------------------------------


REFERENCE = "mobile_sam_reference"


@pytest.fixture
def package(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[str], types.ModuleType]]:
    """``mobile_sam.<name>`` imported with its packages' ``__init__`` files under a test name (drivenav's own import
    is untouched); ``mobile_sam/__init__.py`` itself is skipped (it imports torchvision), timm is the stand-in where
    absent."""
    install_timm_stand_in(monkeypatch)
    spec = importlib.util.find_spec("mobile_sam")
    assert spec is not None and spec.submodule_search_locations
    root = types.ModuleType(REFERENCE)
    root.__path__ = list(spec.submodule_search_locations)
    monkeypatch.setitem(sys.modules, REFERENCE, root)
    yield lambda name: importlib.import_module(f"{REFERENCE}.{name}")
    stand_in_users = (f"{REFERENCE}.", "_drivenav_mobile_sam.modeling.tiny_vit_sam")  # imported with the stand-in
    for name in [m for m in sys.modules if m.startswith(stand_in_users)]:
        del sys.modules[name]


def test_masks_are_the_package_sam_forward_cut_to_their_boxes(
    tiny: MobileSamModel, package: Callable[[str], types.ModuleType]
) -> None:
    """``Sam.forward`` of ``mobile_sam`` on our resized frame and scaled boxes (it normalises, pads, encodes,
    prompts, decodes and post-processes itself) gives our masks before they are cut to the boxes."""
    sam_module = package("modeling.sam")
    reference = sam_module.Sam(copy.deepcopy(tiny.image_encoder), tiny.prompt_encoder, tiny.mask_decoder).eval()
    assert torch.equal(reference.pixel_mean.flatten(), torch.tensor(PIXEL_MEAN))
    assert torch.equal(reference.pixel_std.flatten(), torch.tensor(PIXEL_STD))
    model = segmenter(tiny)
    rgb = disc_frame()
    with torch.inference_mode():
        batch = [{"image": model.resize(rgb)[0], "original_size": (H, W), "boxes": torch.from_numpy(BOXES * 1.6)}]
        expected = reference(batch, multimask_output=False)[0]["masks"][:, 0].numpy()
    ours = model.segment_boxes(rgb, BOXES)
    boxes = FilledBoxSegmenter().segment_boxes(rgb, BOXES)
    assert np.array_equal(ours, expected & boxes)


def test_vit_t_is_the_package_builder_and_loads_its_state_dict(
    package: Callable[[str], types.ModuleType], tmp_path: Path
) -> None:
    """Our ``vit_t`` has the names and shapes of ``build_sam_vit_t``'s model, so the released ``mobile_sam.pt`` (a
    bare state dict) loads into it; TinyViT's attention biases, a buffer derived from the weights when the model is
    put in evaluation mode, are derived from the loaded ones."""
    build_sam = package("build_sam")
    theirs = build_sam.build_sam_vit_t()
    with torch.no_grad():
        for name, weight in theirs.named_parameters():
            if name.endswith("attention_biases"):  # zeros at initialisation
                weight.normal_()
    torch.save(theirs.state_dict(), tmp_path / "mobile_sam.pt")
    ours = load_checkpoint(tmp_path / "mobile_sam.pt")
    assert {k: v.shape for k, v in ours.state_dict().items()} == {k: v.shape for k, v in theirs.state_dict().items()}
    assert all(torch.equal(ours.state_dict()[k], v) for k, v in theirs.state_dict().items())
    attention = MobileSamSegmenter(ours, "cpu").model.image_encoder.layers[1].blocks[0].attn
    assert attention.ab.abs().sum() > 0
    assert torch.equal(attention.ab, attention.attention_biases[:, attention.attention_bias_idxs])


# --- checkpoints and errors ----------------------------------------------------------------------------------------


def test_a_saved_checkpoint_segments_as_the_model_did(tiny: MobileSamModel, tmp_path: Path) -> None:
    path = tmp_path / "tiny_mobile_sam.pt"
    save_checkpoint(tiny, "tiny", path)
    loaded = load_checkpoint(path)
    assert loaded is not tiny
    assert np.array_equal(
        segmenter(loaded).segment_boxes(disc_frame(), BOXES), segmenter(tiny).segment_boxes(disc_frame(), BOXES)
    )


def one_line(error: InputError) -> str:
    message = str(error)
    assert "\n" not in message and "'--segmenter-model'" in message
    return message


def test_checkpoint_errors_are_one_line_naming_the_option(tiny: MobileSamModel, tmp_path: Path) -> None:
    with pytest.raises(InputError) as caught:
        load_checkpoint(tmp_path / "nowhere.pt")
    assert "a MobileSAM checkpoint file (mobile_sam.pt)" in one_line(caught.value)
    (tmp_path / "text.pt").write_text("not a checkpoint")
    with pytest.raises(InputError) as caught:
        load_checkpoint(tmp_path / "text.pt")
    assert "unreadable" in one_line(caught.value)
    torch.save({"architecture": "vit_h", "state_dict": {}}, tmp_path / "other.pt")
    with pytest.raises(InputError) as caught:
        load_checkpoint(tmp_path / "other.pt")
    assert "vit_t, tiny" in one_line(caught.value) and "'vit_h'" in one_line(caught.value)
    state = tiny.state_dict()
    torch.save(
        {"architecture": "tiny", "state_dict": {k: v for k, v in state.items() if "mask_decoder" not in k}},
        tmp_path / "part.pt",
    )
    with pytest.raises(InputError) as caught:
        load_checkpoint(tmp_path / "part.pt")
    assert "missing, e.g. mask_decoder." in one_line(caught.value)
    wrong = {**state, "mask_decoder.iou_token.weight": torch.zeros(1, 5)}
    torch.save({"architecture": "tiny", "state_dict": wrong}, tmp_path / "shape.pt")
    with pytest.raises(InputError) as caught:
        load_checkpoint(tmp_path / "shape.pt")
    assert "size mismatch for mask_decoder.iou_token.weight" in one_line(caught.value)


def test_the_model_code_is_imported_without_the_package_init() -> None:
    """drivenav never runs ``mobile_sam/__init__.py`` (torchvision) nor binds the name ``mobile_sam``."""
    assert model_code("prompt_encoder").PromptEncoder is type(build_architecture("tiny").prompt_encoder)
    assert "mobile_sam" not in sys.modules


def test_bfloat16_keeps_the_prompt_encoder_in_fp32(tiny: MobileSamModel) -> None:
    model = segmenter(tiny, dtype="bfloat16")
    assert model.dtype == torch.bfloat16 and next(model.model.image_encoder.parameters()).dtype == torch.bfloat16
    assert next(model.model.prompt_encoder.parameters()).dtype == torch.float32
    masks = model.segment_boxes(disc_frame(), BOXES)
    assert (
        masks.shape == (len(BOXES), H, W)
        and not (masks & ~FilledBoxSegmenter().segment_boxes(disc_frame(), BOXES)).any()
    )
