"""BLIP-2 and SigLIP as the image-text scorer of the VLFM baseline (Yokoyama et al., ICRA 2024).

VLFM scores every RGB frame against the text "Seems like there is a {target} ahead." (``text_prompt`` of its
``vlfm/policy`` configuration, :data:`VLFM_PROMPT`) with BLIP-2's image-text matching model (LAVIS
``blip2_image_text_matching``, model type ``pretrain``) and spreads the score over its value map. Its
``vlfm/vlm/blip2itm.py`` returns the ITC head's score (``match_head="itc"``): the cosine of the L2-normalised text
embedding (the Q-Former's [CLS] token, projected) with each of the 32 L2-normalised query embeddings of the image,
maximised over the queries. Through transformers that is ``Blip2ForImageTextRetrieval`` with
``use_image_text_matching_head=False``, whose ``logits_per_image`` is that maximum (no temperature). LAVIS's
``blip_caption`` text processor first lower-cases the text and turns ``.!"()*#:;~`` into spaces
(:func:`blip_caption`), and its Q-Former reads at most 32 text tokens (``max_txt_len``).

SigLIP (Zhai et al., ICCV 2023) is the alternative: ``SiglipModel``'s ``logits_per_image`` is the cosine scaled by
the learnt temperature plus the learnt bias, and its sigmoid the probability that text and image match. SigLIP was
trained on texts padded to the text encoder's full length without an attention mask, so the text is padded so and
no mask is passed (as the transformers documentation prescribes).

torch and transformers are the optional ``models`` extra, imported inside functions only; checkpoints are local
(never downloaded) as for the grounders (:mod:`drivenav.semantics.hf_common`).
"""

from __future__ import annotations

import re
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from PIL import Image

from drivenav.semantics.checked import usable_similarity
from drivenav.semantics.hf_common import SCORER_OPTION, load_pair, pick_device
from drivenav.semantics.protocols import ModelCall, ScorePrompt
from drivenav.types import GroundTruth, Observation

VLFM_PROMPT: Final[str] = "Seems like there is a {target} ahead."
"""VLFM's text for the value map (bdaiinstitute/vlfm ``vlfm/policy``: ``text_prompt``), ``{target}`` the goal."""

BLIP2_ITM_CHECKPOINT: Final[str] = "Salesforce/blip2-itm-vit-g"
"""The transformers port of LAVIS's ``blip2_image_text_matching`` ``pretrain`` weights (ViT-g), VLFM's model."""

SIGLIP_CHECKPOINT: Final[str] = "google/siglip-base-patch16-224"
"""SigLIP base, 16-pixel patches at 224 x 224."""

BLIP2_MAX_TEXT_TOKENS: Final[int] = 32
"""LAVIS ``Blip2Qformer.max_txt_len``: the text tokens the Q-Former reads, the rest cut."""

BLIP2_EXPECTED = "a local BLIP-2 image-text retrieval checkpoint directory or a model id in the Hugging Face cache"
SIGLIP_EXPECTED = "a local SigLIP checkpoint directory or a model id in the Hugging Face cache"

_BLIP_CAPTION_PUNCTUATION = re.compile(r'[.!"()*#:;~]')


def blip_caption(text: str) -> str:
    """LAVIS's ``blip_caption`` cleaning: lower case, ``.!"()*#:;~`` as spaces, single spaces, no outer spaces."""
    return " ".join(_BLIP_CAPTION_PUNCTUATION.sub(" ", text.lower()).split())


class _TransformersScorer(ABC):
    """What both scorers share: the prompt, the episode's calls, and one timed score a frame.

    A similarity that is not usable (:func:`~drivenav.semantics.checked.usable_similarity`: a non-finite one, an
    overflow in half precision) is not a score: it is recorded as a ``fallback`` call and answered with 0, the
    value of a frame with no evidence.
    """

    name = ""
    checkpoint = ""  # the default checkpoint
    expected = ""  # what ``--scorer-model`` must name, for the error when it is not on disk

    def __init__(
        self,
        model: str | Path | None = None,
        device: str | None = None,
        prompt: str = VLFM_PROMPT,
        *,
        model_obj: Any = None,
        processor_obj: Any = None,
    ) -> None:
        """Load ``model`` (a checkpoint directory or a cached model id, never downloaded; the class's
        :attr:`checkpoint` when None), or take the already-built ``model_obj`` / ``processor_obj``."""
        model_loader, processor_loader = self.loaders()
        loaded, processor = load_pair(
            model_loader,
            processor_loader,
            model or self.checkpoint,
            self.expected,
            model_obj,
            processor_obj,
            SCORER_OPTION,
        )
        self.model = loaded.to(pick_device(device)).eval()
        self.processor = processor
        self.prompt = prompt
        self.calls: list[ModelCall] = []

    @staticmethod
    @abstractmethod
    def loaders() -> tuple[Callable[..., Any], Callable[..., Any]]:
        """The transformers loaders of the backend's model and processor (imported when called)."""

    def begin_episode(self, truth: GroundTruth | None) -> None:
        """Only the calls restart: a model scores every frame independently and deterministically."""
        self.calls = []

    def text(self, goal: str, prompt: ScorePrompt | None = None) -> str:
        """The text a frame is scored against for ``goal``: the scorer's own (VLFM's), or ``prompt``'s."""
        return self.prompt.format(target=goal) if prompt is None else prompt.text(goal)

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        """The RGB frame's similarity with :meth:`text`."""
        start = time.perf_counter()
        value = self.similarity(Image.fromarray(observation.rgb), self.text(goal, prompt))
        usable = usable_similarity(value)
        outcome = "ok" if usable is not None else "fallback"
        self.calls.append(ModelCall("score", (time.perf_counter() - start) * 1000.0, outcome))
        return usable if usable is not None else 0.0

    @abstractmethod
    def similarity(self, image: Image.Image, text: str) -> float:
        """The backend's similarity of ``image`` and ``text``."""

    def _forward(self, tensors: dict[str, Any], **options: Any) -> Any:
        """One pass without gradients; the tensors follow the model onto its device, the pixels take its dtype."""
        import torch

        moved = {key: value.to(self.model.device) for key, value in tensors.items()}
        moved["pixel_values"] = moved["pixel_values"].to(self.model.dtype)
        with torch.inference_mode():
            return self.model(**moved, **options)


class Blip2ItmScorer(_TransformersScorer):
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` with BLIP-2's ITC cosine, as VLFM does
    (module docstring): in [-1, 1]."""

    name = "blip2-itm"
    checkpoint = BLIP2_ITM_CHECKPOINT
    expected = BLIP2_EXPECTED

    @staticmethod
    def loaders() -> tuple[Callable[..., Any], Callable[..., Any]]:
        from transformers import Blip2ForImageTextRetrieval, Blip2Processor

        return Blip2ForImageTextRetrieval.from_pretrained, Blip2Processor.from_pretrained

    def similarity(self, image: Image.Image, text: str) -> float:
        """The maximum over the image's query embeddings of their cosine with the text's.

        The image and the text go through the processor's halves separately: a BLIP-2 processor that prepends
        image tokens for a language model (``num_query_tokens``) must not do so for the Q-Former's text.
        """
        pixels = self.processor.image_processor(images=image, return_tensors="pt")["pixel_values"]
        tokens = self.processor.tokenizer(
            blip_caption(text), truncation=True, max_length=BLIP2_MAX_TEXT_TOKENS, return_tensors="pt"
        )
        tensors = {"pixel_values": pixels, "input_ids": tokens["input_ids"], "attention_mask": tokens["attention_mask"]}
        outputs = self._forward(tensors, use_image_text_matching_head=False)
        return float(outputs.logits_per_image.float().item())


class SiglipScorer(_TransformersScorer):
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` with SigLIP's match probability
    (module docstring): in [0, 1]."""

    name = "siglip"
    checkpoint = SIGLIP_CHECKPOINT
    expected = SIGLIP_EXPECTED

    @staticmethod
    def loaders() -> tuple[Callable[..., Any], Callable[..., Any]]:
        from transformers import SiglipModel, SiglipProcessor

        return SiglipModel.from_pretrained, SiglipProcessor.from_pretrained

    def similarity(self, image: Image.Image, text: str) -> float:
        """``sigmoid(exp(logit_scale) * cosine + logit_bias)`` of the image and the text padded to full length."""
        length = self.model.config.text_config.max_position_embeddings
        batch = self.processor(
            images=image, text=[text], padding="max_length", truncation=True, max_length=length, return_tensors="pt"
        )
        outputs = self._forward({"pixel_values": batch["pixel_values"], "input_ids": batch["input_ids"]})
        return float(outputs.logits_per_image.float().sigmoid().item())
