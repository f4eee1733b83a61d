"""MobileSAM as the box segmenter: OWLv2's and Grounding DINO's boxes become instance masks (paper Sec. V-D, where
OWLv2 is paired with MobileSAM; VLFM and ApexNav pair their detectors with it too).

MobileSAM (Zhang et al., 2023) is SAM with its image encoder distilled into TinyViT-5M. Per frame, with at least one
box: the frame's longest side is resized to the encoder's input (1,024 pixels; bilinear, antialiased), normalised
with ImageNet's mean and standard deviation in 0-255 units and zero-padded at the bottom and right to a square; the
image encoder runs once; each box, scaled like the frame, prompts SAM's prompt encoder, and SAM's mask decoder gives
one mask per box (single-mask output) as low-resolution logits, which are upscaled to the padded input, cropped to
the resized frame, resized to the frame and thresholded at 0 (SAM's post-processing). Each mask is then limited to
its box (:func:`~drivenav.semantics.boxes.inside_boxes`): the detector decided where the object is. The prompt
encoder stays in fp32 whatever ``models.dtype`` is: box corners near 1,024 pixels would move by up to 4 pixels in
bf16.

The model code is the ``mobilesam-mirror`` package's (``mobile_sam.modeling``, Apache-2.0, no weights). Its
``mobile_sam/__init__.py`` imports torchvision (for its predictor's resizing) and ``mobile_sam/modeling/__init__.py``
imports timm (for TinyViT's layers), so the modules are imported one by one under a private package name
(:func:`model_code`): SAM's prompt encoder and mask decoder need torch only, TinyViT timm too, and nothing here needs
torchvision. The weights come from a checkpoint file (``--segmenter-model``, :func:`load_checkpoint`): the released
``mobile_sam.pt`` (a state dict of the ``vit_t`` architecture) or a file written by :func:`save_checkpoint` (an
architecture's name and its state dict; the tests save the ``tiny`` one). :func:`build_architecture` makes an
architecture with random weights (the benchmarks).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any, Final

import numpy as np
import torch
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.semantics.boxes import inside_boxes
from drivenav.semantics.hf_common import compile_modules, place_model
from drivenav.semantics.registry import MOBILESAM_EXPECTED

SEGMENTER_OPTION = "--segmenter-model"
PACKAGE = "mobile_sam"
"""The import name of the ``mobilesam-mirror`` distribution."""
_ALIAS = "_drivenav_mobile_sam"
"""The private package name under which :func:`model_code` imports ``mobile_sam``'s modules."""

PIXEL_MEAN: Final[tuple[float, float, float]] = (123.675, 116.28, 103.53)
PIXEL_STD: Final[tuple[float, float, float]] = (58.395, 57.12, 57.375)
"""SAM's (and MobileSAM's) input normalisation: ImageNet's mean and standard deviation in 0-255 units."""
MASK_THRESHOLD: Final[float] = 0.0
"""A pixel is in the mask where the decoder's logit is above this (SAM's ``mask_threshold``)."""


def model_code(module: str) -> types.ModuleType:
    """``mobile_sam.modeling.<module>`` of the installed ``mobilesam-mirror``, imported without running the package's
    ``__init__`` files (module docstring): a ``ModuleNotFoundError`` names what is missing (the package, or timm for
    ``tiny_vit_sam``)."""
    if _ALIAS not in sys.modules:
        spec = importlib.util.find_spec(PACKAGE)
        if spec is None or not spec.submodule_search_locations:
            raise ModuleNotFoundError(f"No module named {PACKAGE!r}", name="mobilesam-mirror")
        root = list(spec.submodule_search_locations)
        for name, path in ((_ALIAS, root), (f"{_ALIAS}.modeling", [str(Path(root[0]) / "modeling")])):
            package = types.ModuleType(name)
            package.__path__ = path
            sys.modules[name] = package
    return importlib.import_module(f"{_ALIAS}.modeling.{module}")


class MobileSamModel(torch.nn.Module):
    """SAM's three parts under the names of ``mobile_sam``'s ``Sam`` (so that its state dicts load): an image encoder
    with a square input of ``img_size`` pixels, the prompt encoder and the mask decoder (``Sam``'s normalisation
    constants are :data:`PIXEL_MEAN` and :data:`PIXEL_STD`, not weights)."""

    def __init__(self, image_encoder: Any, prompt_encoder: Any, mask_decoder: Any) -> None:
        super().__init__()
        self.image_encoder = image_encoder
        self.prompt_encoder = prompt_encoder
        self.mask_decoder = mask_decoder


def _sam_heads(width: int, image_size: int, patch: int, decoder: Mapping[str, int]) -> tuple[Any, Any]:
    """SAM's prompt encoder and mask decoder for ``width``-feature embeddings of a ``image_size``-pixel input in
    ``patch``-pixel cells (three extra masks for multimask output, as SAM has)."""
    prompt = model_code("prompt_encoder").PromptEncoder(
        embed_dim=width,
        image_embedding_size=(image_size // patch, image_size // patch),
        input_image_size=(image_size, image_size),
        mask_in_chans=decoder["mask_in_chans"],
    )
    transformer = model_code("transformer").TwoWayTransformer(
        depth=decoder["depth"], embedding_dim=width, mlp_dim=decoder["mlp_dim"], num_heads=decoder["heads"]
    )
    mask_decoder = model_code("mask_decoder").MaskDecoder(
        num_multimask_outputs=3,
        transformer=transformer,
        transformer_dim=width,
        iou_head_depth=decoder["iou_depth"],
        iou_head_hidden_dim=decoder["iou_width"],
    )
    return prompt, mask_decoder


def vit_t() -> MobileSamModel:
    """The released MobileSAM (``vit_t``): TinyViT-5M (stage widths 64-128-160-320, depths 2-2-6-2, heads
    2-4-5-10, windows 7-7-14-7) at 1,024 pixels into 256 features, and SAM's heads (two-way transformer of depth 2,
    MLP 2,048, 8 heads; IoU head of depth 3 and width 256). Needs timm."""
    encoder = model_code("tiny_vit_sam").TinyViT(
        img_size=1024,
        in_chans=3,
        num_classes=1000,
        embed_dims=[64, 128, 160, 320],
        depths=[2, 2, 6, 2],
        num_heads=[2, 4, 5, 10],
        window_sizes=[7, 7, 14, 7],
        mlp_ratio=4.0,
        drop_rate=0.0,
        drop_path_rate=0.0,
        use_checkpoint=False,
        mbconv_expand_ratio=4.0,
        local_conv_size=3,
        layer_lr_decay=0.8,
    )
    decoder = {"mask_in_chans": 16, "depth": 2, "mlp_dim": 2048, "heads": 8, "iou_depth": 3, "iou_width": 256}
    return MobileSamModel(encoder, *_sam_heads(256, 1024, 16, decoder))


TINY_SIZE: Final[int] = 64
"""The tiny architecture's input: 4 x 4 cells of 16 pixels."""


def tiny() -> MobileSamModel:
    """The tests' architecture: SAM's ViT image encoder with one global-attention layer of 32 features at
    :data:`TINY_SIZE` pixels, and SAM's heads at 32 features (torch only; a forward takes milliseconds)."""
    encoder = model_code("image_encoder").ImageEncoderViT(
        img_size=TINY_SIZE,
        patch_size=16,
        in_chans=3,
        embed_dim=32,
        depth=1,
        num_heads=2,
        mlp_ratio=2.0,
        out_chans=32,
        qkv_bias=True,
        norm_layer=partial(torch.nn.LayerNorm, eps=1e-6),
        use_rel_pos=True,
        window_size=0,
        global_attn_indexes=(0,),
    )
    decoder = {"mask_in_chans": 4, "depth": 1, "mlp_dim": 64, "heads": 2, "iou_depth": 1, "iou_width": 32}
    return MobileSamModel(encoder, *_sam_heads(32, TINY_SIZE, 16, decoder))


ARCHITECTURES: dict[str, Callable[[], MobileSamModel]] = {"vit_t": vit_t, "tiny": tiny}
"""The architectures a checkpoint may name; a bare state dict is ``vit_t`` (the released ``mobile_sam.pt``)."""


def build_architecture(name: str) -> MobileSamModel:
    """The architecture ``name`` with random weights (in the current default device)."""
    return ARCHITECTURES[name]()


def save_checkpoint(model: MobileSamModel, architecture: str, path: Path) -> None:
    """``model``'s weights as a checkpoint :func:`load_checkpoint` reads: ``{"architecture": name, "state_dict":
    ...}`` (``torch.save``)."""
    if architecture not in ARCHITECTURES:
        raise ValueError(f"unknown MobileSAM architecture {architecture!r}")
    torch.save({"architecture": architecture, "state_dict": model.state_dict()}, path)


def load_checkpoint(path: Path) -> MobileSamModel:
    """The model a checkpoint file holds (module docstring), on the CPU; a missing, unreadable or mismatched file is
    an :class:`~drivenav.errors.InputError` naming ``--segmenter-model``."""
    if not path.is_file():
        raise InputError("command line", SEGMENTER_OPTION, MOBILESAM_EXPECTED, str(path))
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # a pickle, a zip or a torch error: the file is not a checkpoint
        raise InputError(path, SEGMENTER_OPTION, MOBILESAM_EXPECTED, f"unreadable: {_first_line(error)}") from None
    if not isinstance(saved, dict):
        raise InputError(path, SEGMENTER_OPTION, MOBILESAM_EXPECTED, type(saved).__name__)
    name, state = (saved.get("architecture"), saved.get("state_dict")) if "state_dict" in saved else ("vit_t", saved)
    if name not in ARCHITECTURES or not isinstance(state, dict):
        raise InputError(path, SEGMENTER_OPTION, f"one of the architectures {', '.join(ARCHITECTURES)}", name)
    model = build_architecture(name)
    expected = f"the weights of MobileSAM's {name} architecture"
    try:
        loaded = model.load_state_dict(state, strict=False)
    except RuntimeError as error:  # a weight of another shape
        raise InputError(path, SEGMENTER_OPTION, expected, _mismatch(error)) from None
    for problem, keys in (("missing", loaded.missing_keys), ("unexpected", loaded.unexpected_keys)):
        if keys:
            raise InputError(path, SEGMENTER_OPTION, expected, f"{len(keys)} {problem}, e.g. {keys[0]}")
    return model


def _first_line(error: BaseException) -> str:
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__


def _mismatch(error: RuntimeError) -> str:
    """The first problem ``load_state_dict`` lists (its message starts with a header line)."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return lines[1] if len(lines) > 1 else _first_line(error)


class MobileSamSegmenter:
    """Implements :class:`~drivenav.semantics.boxes.BoxSegmenter` with a MobileSAM model (module docstring).

    ``model`` is placed on ``device`` (CUDA when visible) in ``dtype`` (``models.dtype``), its prompt encoder in
    fp32; ``compile_backend`` compiles the image encoder and the mask decoder. A frame without boxes costs nothing.
    """

    def __init__(
        self, model: MobileSamModel, device: str | None = None, dtype: str = "auto", compile_backend: str = ""
    ) -> None:
        self.model = place_model(model, device, dtype)
        self.model.prompt_encoder.float()
        weight = next(self.model.mask_decoder.parameters())
        self.device: torch.device = weight.device
        self.dtype: torch.dtype = weight.dtype
        self.size: int = self.model.image_encoder.img_size
        self._mean = torch.tensor(PIXEL_MEAN, device=self.device).view(3, 1, 1)
        self._std = torch.tensor(PIXEL_STD, device=self.device).view(3, 1, 1)
        with torch.inference_mode():
            self._dense_pe = self.model.prompt_encoder.get_dense_pe().to(self.dtype)
        compile_modules([self.model.image_encoder, self.model.mask_decoder], compile_backend)

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
        height, width = rgb.shape[:2]
        if len(boxes) == 0:
            return np.zeros((0, height, width), dtype=bool)
        with torch.inference_mode():
            pixels, resized = self.preprocess(rgb)
            logits = self.decode(self.model.image_encoder(pixels), boxes, (height, width), resized)
            masks = self.postprocess(logits, (height, width), resized)
        return inside_boxes(masks.cpu().numpy(), boxes)

    def preprocess(self, rgb: NDArray[np.uint8]) -> tuple[torch.Tensor, tuple[int, int]]:
        """The frame as the encoder's padded square input, and its resized ``(height, width)`` inside it."""
        image = self.resize(rgb)
        resized = (image.shape[-2], image.shape[-1])
        image = (image - self._mean) / self._std
        padded = torch.nn.functional.pad(image, (0, self.size - resized[1], 0, self.size - resized[0]))
        return padded.to(self.dtype), resized

    def resize(self, rgb: NDArray[np.uint8]) -> torch.Tensor:
        """The frame ``(1, 3, h, w)`` in 0-255 floats on the device, its longest side resized to the input's."""
        height, width = rgb.shape[:2]
        scale = self.size / max(height, width)
        resized = (int(height * scale + 0.5), int(width * scale + 0.5))
        image = torch.from_numpy(np.ascontiguousarray(rgb)).to(self.device).permute(2, 0, 1)[None].float()
        return torch.nn.functional.interpolate(image, resized, mode="bilinear", align_corners=False, antialias=True)

    def decode(
        self, embedding: torch.Tensor, boxes: NDArray[np.float32], frame: tuple[int, int], resized: tuple[int, int]
    ) -> torch.Tensor:
        """The decoder's low-resolution mask logits ``(N, 1, h, w)``, one per box (boxes scaled like the frame)."""
        scale = np.array([resized[1] / frame[1], resized[0] / frame[0]] * 2, dtype=np.float32)
        prompts = torch.from_numpy(np.asarray(boxes, dtype=np.float32) * scale).to(self.device)
        sparse, dense = self.model.prompt_encoder(points=None, boxes=prompts, masks=None)
        logits, _ = self.model.mask_decoder(
            image_embeddings=embedding,
            image_pe=self._dense_pe,
            sparse_prompt_embeddings=sparse.to(self.dtype),
            dense_prompt_embeddings=dense.to(self.dtype),
            multimask_output=False,
        )
        return logits  # type: ignore[no-any-return]

    def postprocess(self, logits: torch.Tensor, frame: tuple[int, int], resized: tuple[int, int]) -> torch.Tensor:
        """The masks ``(N, H, W)`` at the frame's size: the logits upscaled to the padded input, cropped to the
        resized frame, resized to the frame, above :data:`MASK_THRESHOLD`."""
        square = torch.nn.functional.interpolate(logits, (self.size, self.size), mode="bilinear", align_corners=False)
        cropped = square[..., : resized[0], : resized[1]]
        masks = torch.nn.functional.interpolate(cropped, frame, mode="bilinear", align_corners=False)
        return masks[:, 0] > MASK_THRESHOLD
