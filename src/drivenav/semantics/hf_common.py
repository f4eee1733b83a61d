"""Plumbing shared by the transformers models: the grounders SAM3 (the paper's detector, Sec. V-A), OWLv2 and
Grounding DINO (+ a box segmenter, the grounding-backbone comparison of Sec. V-D), and the VLFM baseline's scorers
BLIP-2 and SigLIP.

torch and transformers are the optional ``models`` extra, so they are imported inside functions only. Weights are
never downloaded: a checkpoint is a local directory written by ``save_pretrained`` or a model id already in the
Hugging Face cache (``local_files_only=True``); weights that are not there are an
:class:`~drivenav.errors.InputError` that names the option that chose them (``--detector-model``,
``--scorer-model``).

The grounders share :class:`TransformersGrounder`: the model in the chosen dtype on its device (``models.dtype``:
``auto`` is bf16 on a CUDA device that supports it, fp32 elsewhere; TF32 matmuls on CUDA in fp32), the images
preprocessed on that device by torchvision's fast image processor, the text features of each phrase computed once
per episode and the vision features of the last frame reused while several phrases are tried on it (prompt
enrichment, Sec. IV-B). ``models.compile`` (``--compile``) compiles the modules each frame runs through with
``torch.compile`` (:func:`compile_modules`); the text encoders, run once per phrase and episode, stay eager.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.semantics.protocols import Detection
from drivenav.types import GroundTruth, Observation

DETECTOR_OPTION = "--detector-model"
SCORER_OPTION = "--scorer-model"

T = TypeVar("T")


def pick_device(device: str | None) -> str:
    """``device`` when given, else ``cuda`` when a GPU is visible, else ``cpu``."""
    if device is not None:
        return device
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"


def load_local(loader: Callable[..., T], model: str | Path, expected: str, option: str = DETECTOR_OPTION) -> T:
    """``loader(model, local_files_only=True)``; weights that are not on disk become a one-line InputError naming
    ``option``.

    transformers reports a missing directory, a directory without weights and an id absent from the cache as
    ``OSError``, a path that is not a valid id as ``HFValidationError``. Other errors (a checkpoint whose image
    processor needs an uninstalled backend such as torchvision) pass through with their own message.
    """
    from huggingface_hub.errors import HFValidationError

    try:
        return loader(str(model), local_files_only=True)
    except (OSError, HFValidationError) as exc:
        raise InputError("command line", option, expected, str(model)) from exc


def load_pair(
    model_loader: Callable[..., Any],
    processor_loader: Callable[..., Any],
    model: str | Path,
    expected: str,
    model_obj: Any,
    processor_obj: Any,
    option: str = DETECTOR_OPTION,
) -> tuple[Any, Any]:
    """The given model and processor objects, each loaded from ``model`` where it was not given (a missing one is
    an InputError naming ``option``)."""
    loaded_model = model_obj if model_obj is not None else load_local(model_loader, model, expected, option)
    processor = processor_obj if processor_obj is not None else load_local(processor_loader, model, expected, option)
    return loaded_model, processor


def fit_phrase(tokenizer: Any, phrase: str, max_tokens: int) -> str:
    """``phrase`` without as many trailing words as needed for its tokens (bos and eos included) to fit.

    The text encoders have fixed position tables (OWLv2 16 tokens, SAM3 32) and the processors do not truncate, so
    a long enriched prompt (Sec. IV-B) would fail; like CLIP's own truncation this keeps the start. One word is
    always kept. The measuring is quiet: the tokenizer's warning that a sequence is longer than the model's is for
    sequences the model would see, which a fitted phrase is not.
    """
    words = phrase.split()
    while len(words) > 1 and len(tokenizer(" ".join(words), verbose=False)["input_ids"]) > max_tokens:
        words.pop()
    return " ".join(words)


DTYPE_AUTO = "auto"
"""``models.dtype``'s default: bf16 on a CUDA device that supports it (half the memory, about twice the speed of
fp32 on an H100 in issue 37's measurements), fp32 elsewhere (CPUs gain little from bf16, and the tests compare
exactly)."""


def resolve_dtype(name: str, device: str) -> Any:
    """The ``torch.dtype`` that ``models.dtype`` names on ``device`` (``auto``: see :data:`DTYPE_AUTO`)."""
    import torch

    if name != DTYPE_AUTO:
        dtype: torch.dtype = getattr(torch, name)
        return dtype
    on_cuda = torch.device(device).type == "cuda"
    return torch.bfloat16 if on_cuda and torch.cuda.is_bf16_supported() else torch.float32


def place_model(model: Any, device: str | None, dtype: str) -> Any:
    """``model`` in eval mode on ``device`` (:func:`pick_device`) in the dtype ``dtype`` names.

    In fp32 on CUDA, matrix products and cuDNN convolutions may use TF32 (a process-wide torch setting; about twice
    the speed of strict fp32 on an H100 for SAM3, issue 37).
    """
    import torch

    chosen = pick_device(device)
    torch_dtype = resolve_dtype(dtype, chosen)
    if torch_dtype == torch.float32 and torch.device(chosen).type == "cuda":
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
    return model.to(device=chosen, dtype=torch_dtype).eval()


def require_fast_image_processor(processor: Any) -> Any:
    """``processor`` when its image half is torchvision's (fast, runs on the model's device); else an ImportError
    naming torchvision (the registry turns it into the one-line "models extra" error).

    transformers falls back to the PIL image processor when torchvision is missing; for OWLv2 that one costs about
    300 ms a frame (issue 37), so it is refused rather than silently used.
    """
    if getattr(processor.image_processor, "backend", None) != "torchvision":
        raise ImportError("torchvision (the fast image processor) is not installed")
    return processor


def load_fast_processor(loader: Callable[..., Any]) -> Callable[..., Any]:
    """``loader`` (a processor's ``from_pretrained``) asking for torchvision's image processor, refusing another."""

    def load(model: str, **kwargs: Any) -> Any:
        return require_fast_image_processor(loader(model, backend="torchvision", **kwargs))

    return load


COMPILE_BACKEND = "inductor"
"""``torch.compile``'s backend for ``models.compile`` (its default: generated Triton kernels on CUDA, C++ on the
CPU). An empty backend name leaves a model eager."""


def compile_backend_for(compile_models: bool) -> str:
    """The backend :func:`compile_modules` uses for ``models.compile``: :data:`COMPILE_BACKEND`, or none."""
    return COMPILE_BACKEND if compile_models else ""


def compile_modules(modules: Sequence[Any], backend: str) -> None:
    """Each module's forward compiled in place with ``torch.compile`` on ``backend`` (``nn.Module.compile``: a call
    of the module runs the compiled forward, compiled at its first call and again when its input shapes change);
    nothing for an empty ``backend``."""
    if backend:
        for module in modules:
            module.compile(backend=backend)


class FrameFeatures:
    """The vision features of the last frame seen, reused while several phrases are tried on that frame.

    A frame is the same when its step and its pixels are (the pixels are compared with a private copy, so a world
    that reuses its image buffer cannot serve stale features); only the last frame is kept.
    """

    def __init__(self) -> None:
        self._step = -1
        self._rgb: NDArray[np.uint8] | None = None
        self._features: Any = None

    def get(self, observation: Observation, encode: Callable[[NDArray[np.uint8]], Any]) -> Any:
        """The features of ``observation``'s frame: the kept ones when it is the last frame, else ``encode``'s."""
        rgb = observation.rgb
        if self._rgb is None or observation.step != self._step or not np.array_equal(rgb, self._rgb):
            self._features = encode(rgb)
            self._step, self._rgb = observation.step, rgb.copy()
        return self._features

    def clear(self) -> None:
        self._step, self._rgb, self._features = -1, None, None


class TransformersGrounder(ABC):
    """A :class:`~drivenav.semantics.protocols.Grounder` over a transformers model, split into stages that a
    subclass fills in: :meth:`encode_text` (a phrase's features), :meth:`encode_vision` (a batch of preprocessed
    frames' features), :meth:`decode_rows` (both into the model's raw output, a phrase a row) and :meth:`postprocess`
    (raw output into detections per row). :meth:`preprocess` is shared.

    :meth:`segment` caches: a phrase's text features for the episode (cleared by :meth:`begin_episode`), the last
    frame's vision features (:class:`FrameFeatures`). Every stage runs without gradients; results are the same as one
    plain forward of the model on the processor's image and text (the tests check it exactly in fp32).
    ``compile_backend`` (:func:`compile_backend_for`) compiles :meth:`compiled_modules`.
    """

    name = ""

    def __init__(self, model: Any, processor: Any, device: str | None, dtype: str, compile_backend: str = "") -> None:
        self.model = place_model(model, device, dtype)
        self.processor = processor
        fast = getattr(processor.image_processor, "backend", None) == "torchvision"
        self._image_kwargs: dict[str, Any] = {"device": self.model.device} if fast else {}
        self._texts: dict[str, Any] = {}
        self._frame = FrameFeatures()
        compile_modules(self.compiled_modules(), compile_backend)

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Forgets the episode's text features and the last frame (a new episode brings new phrases)."""
        self._texts.clear()
        self._frame.clear()

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        """Every instance of ``phrase`` in the frame, best score first, masks at the frame's size.

        A phrase longer than the text encoder's positions loses its last words (:func:`fit_phrase`); the detections
        still carry ``phrase`` as given.
        """
        import torch

        with torch.inference_mode():
            text = self.text_features(phrase)
            vision = self._frame.get(observation, lambda rgb: self.encode_vision(self.preprocess([rgb])))
            return self.postprocess(self.decode_rows(vision, [text]), [observation.rgb], [phrase])[0]

    def segment_batch(self, frames: Sequence[NDArray[np.uint8]], phrase: str) -> list[list[Detection]]:
        """:meth:`segment` for several frames of one size in one forward (no frame cache): detections per frame."""
        return self.segment_rows(self.preprocess(frames), frames, [(i, phrase) for i in range(len(frames))])

    def segment_rows(
        self,
        pixels: Any,
        frames: Sequence[NDArray[np.uint8]],
        rows: Sequence[tuple[int, str]],
        lap: Callable[[str], None] | None = None,
    ) -> list[list[Detection]]:
        """Each row's phrase in its frame (``rows``: the frame's index in ``frames``, the phrase) in one forward: the
        vision encoder once over ``frames`` (``pixels``, :meth:`preprocess`'s batch, so that a server preprocesses
        the next batch while this one runs), then the rest over the rows, each with its own phrase's text features
        (a server's batch of workers looking for different objects, or the phrases of one frame). ``lap`` is called
        with ``"forward"`` once the model's output is there and with ``"postprocess"`` once the detections are (a
        server's timing of its stages)."""
        import torch

        with torch.inference_mode():
            vision = self.encode_vision(pixels)
            index = [i for i, _ in rows]
            if index != list(range(len(frames))):
                vision = select_rows(vision, torch.tensor(index, device=self.model.device), len(frames))
            outputs = self.decode_rows(vision, [self.text_features(phrase) for _, phrase in rows])
            if lap is not None:
                lap("forward")
            found = self.postprocess(outputs, [frames[i] for i in index], [phrase for _, phrase in rows])
        if lap is not None:
            lap("postprocess")
        return found

    def join_pixels(self, parts: Sequence[Any]) -> Any:
        """Pixel batches of :meth:`preprocess` (frames of one size) as one batch, in their order."""
        import torch

        return torch.cat(list(parts))

    def text_features(self, phrase: str) -> Any:
        """``phrase``'s text features, encoded on its first use in the episode."""
        if phrase not in self._texts:
            self._texts[phrase] = self.encode_text(fit_phrase(self.processor.tokenizer, phrase, self.max_text_tokens()))
        return self._texts[phrase]

    def max_text_tokens(self) -> int:
        """The most tokens (bos and eos included) a phrase may have: the text encoder's positions."""
        limit: int = self.model.config.text_config.max_position_embeddings
        return limit

    def preprocess(self, frames: Sequence[NDArray[np.uint8]]) -> Any:
        """The frames as the model's pixel batch, on its device in its dtype (resized there by a fast processor)."""
        batch = self.processor.image_processor(list(frames), return_tensors="pt", **self._image_kwargs)
        return batch["pixel_values"].to(self.model.device, self.model.dtype)

    def tokens(self, text: str) -> tuple[Any, Any]:
        """``text``'s token ids and attention mask as the processor pads them, on the model's device."""
        batch = self.processor(text=[text], return_tensors="pt")
        return batch["input_ids"].to(self.model.device), batch["attention_mask"].to(self.model.device)

    @abstractmethod
    def compiled_modules(self) -> list[Any]:
        """The modules every frame runs through (what ``models.compile`` compiles)."""

    @abstractmethod
    def encode_text(self, text: str) -> Any:
        """The text features of ``text`` (already fitted to the encoder)."""

    @abstractmethod
    def encode_vision(self, pixels: Any) -> Any:
        """The vision features of a pixel batch."""

    @abstractmethod
    def decode_rows(self, vision: Any, texts: Sequence[Any]) -> Any:
        """The model's raw output for a batch of vision features, each row with its own phrase's text features
        (``texts``, one per row)."""

    @abstractmethod
    def postprocess(
        self, outputs: Any, frames: Sequence[NDArray[np.uint8]], phrases: Sequence[str]
    ) -> list[list[Detection]]:
        """The detections of each row from the raw output (its frame, its phrase), best score first."""


def select_rows(value: Any, index: Any, batch: int) -> Any:
    """``value`` (a model's output: tensors, tuples and lists of them, ``ModelOutput`` records, a grounder's own
    dataclass records of them) with every tensor of ``batch`` rows re-indexed along its first dimension by ``index``
    (a frame's features repeated for each row that reads them); anything else is kept as it is."""
    import torch
    from transformers.utils.generic import ModelOutput

    if isinstance(value, torch.Tensor):
        return value.index_select(0, index) if value.dim() and value.shape[0] == batch else value
    if isinstance(value, ModelOutput):
        return type(value)(**{key: select_rows(item, index, batch) for key, item in value.items()})
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {
            field.name: select_rows(getattr(value, field.name), index, batch) for field in dataclasses.fields(value)
        }
        return dataclasses.replace(value, **fields)
    if isinstance(value, (tuple, list)):
        return type(value)(select_rows(item, index, batch) for item in value)
    return value


def ranked_detections(scores: NDArray[np.floating[Any]], masks: NDArray[np.bool_], phrase: str) -> list[Detection]:
    """One :class:`Detection` per instance, best score first; empty masks are dropped (nothing to approach)."""
    order = np.argsort(-scores, kind="stable")
    return [Detection(masks[i], float(scores[i]), phrase) for i in order if masks[i].any()]
