"""Plumbing shared by the transformers grounders: SAM3 (the paper's detector, Sec. V-A) and
OWLv2 (+ a box segmenter, the grounding-backbone comparison of Sec. V-D).

torch and transformers are the optional ``models`` extra, so they are imported inside functions only. Weights are
never downloaded: a checkpoint is a local directory written by ``save_pretrained`` or a model id already in the
Hugging Face cache (``local_files_only=True``); weights that are not there are an
:class:`~drivenav.errors.InputError` that names the ``--detector-model`` option.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.semantics.protocols import Detection

DETECTOR_OPTION = "--detector-model"

T = TypeVar("T")


def pick_device(device: str | None) -> str:
    """``device`` when given, else ``cuda`` when a GPU is visible, else ``cpu``."""
    if device is not None:
        return device
    import torch

    return "cuda" if torch.cuda.is_available() else "cpu"


def load_local(loader: Callable[..., T], model: str | Path, expected: str) -> T:
    """``loader(model, local_files_only=True)``; weights that are not on disk become a one-line InputError.

    transformers reports a missing directory, a directory without weights and an id absent from the cache as
    ``OSError``, a path that is not a valid id as ``HFValidationError``. Other errors (a checkpoint whose image
    processor needs an uninstalled backend such as torchvision) pass through with their own message.
    """
    from huggingface_hub.errors import HFValidationError

    try:
        return loader(str(model), local_files_only=True)
    except (OSError, HFValidationError) as exc:
        raise InputError("command line", DETECTOR_OPTION, expected, str(model)) from exc


def load_pair(
    model_loader: Callable[..., Any],
    processor_loader: Callable[..., Any],
    model: str | Path,
    expected: str,
    model_obj: Any,
    processor_obj: Any,
) -> tuple[Any, Any]:
    """The given model and processor objects, each loaded from ``model`` where it was not given."""
    loaded_model = model_obj if model_obj is not None else load_local(model_loader, model, expected)
    processor = processor_obj if processor_obj is not None else load_local(processor_loader, model, expected)
    return loaded_model, processor


def fit_phrase(tokenizer: Any, phrase: str, max_tokens: int) -> str:
    """``phrase`` without as many trailing words as needed for its tokens (bos and eos included) to fit.

    The text encoders have fixed position tables (OWLv2 16 tokens, SAM3 32) and the processors do not truncate, so
    a long enriched prompt (Sec. IV-B) would fail; like CLIP's own truncation this keeps the start. One word is
    always kept.
    """
    words = phrase.split()
    while len(words) > 1 and len(tokenizer(" ".join(words))["input_ids"]) > max_tokens:
        words.pop()
    return " ".join(words)


def run_model(model: Any, batch: Mapping[str, Any]) -> Any:
    """One forward pass without gradients on the processor's image and text tensors.

    The inputs follow the model onto its device; the pixels also take its dtype (a half-precision checkpoint).
    """
    import torch

    with torch.inference_mode():
        return model(
            pixel_values=batch["pixel_values"].to(model.device, model.dtype),
            input_ids=batch["input_ids"].to(model.device),
            attention_mask=batch["attention_mask"].to(model.device),
        )


def ranked_detections(scores: NDArray[np.floating[Any]], masks: NDArray[np.bool_], phrase: str) -> list[Detection]:
    """One :class:`Detection` per instance, best score first; empty masks are dropped (nothing to approach)."""
    order = np.argsort(-scores, kind="stable")
    return [Detection(masks[i], float(scores[i]), phrase) for i in order if masks[i].any()]
