"""SAM3 as the grounder: promptable concept segmentation of a noun phrase (paper Sec. IV-B, V-A).

DRIVE-Nav uses SAM3 directly as its open-vocabulary detector: every step it segments the target category (or an
enriched phrase) in the RGB frame and returns one instance mask per match. Through transformers this is
``Sam3Processor`` (image + text prompt) -> ``Sam3Model`` -> ``post_process_instance_segmentation``, whose score is
the query's probability times the image-level presence probability. The released processor's image half needs
torchvision. The paper measures about 270 ms per SAM3 call on its RTX 4090 deployment machine (Sec. V-E).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from PIL import Image

from drivenav.semantics.hf_common import fit_phrase, load_pair, pick_device, ranked_detections, run_model
from drivenav.semantics.protocols import Detection
from drivenav.types import GroundTruth, Observation

SAM3_EXPECTED = "a local SAM3 checkpoint directory or a model id in the Hugging Face cache"


class Sam3Grounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with a transformers SAM3 checkpoint.

    ``model`` is a checkpoint directory or a cached model id (never downloaded). Instances scoring strictly above
    ``score_threshold`` are kept; mask probabilities above ``mask_threshold`` form the mask, resized to the frame.
    ``model_obj`` / ``processor_obj`` inject already-built objects (tests, shared GPU copies) instead of loading.
    """

    name = "sam3"

    def __init__(
        self,
        model: str | Path = "facebook/sam3",
        device: str | None = None,
        score_threshold: float = 0.5,
        mask_threshold: float = 0.5,
        *,
        model_obj: Any = None,
        processor_obj: Any = None,
    ) -> None:
        from transformers import Sam3Model, Sam3Processor

        loaded, self.processor = load_pair(
            Sam3Model.from_pretrained, Sam3Processor.from_pretrained, model, SAM3_EXPECTED, model_obj, processor_obj
        )
        self.model = loaded.to(pick_device(device)).eval()
        self.score_threshold = score_threshold
        self.mask_threshold = mask_threshold

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Nothing to reset: SAM3 grounds every frame independently and deterministically."""

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        """Every instance of ``phrase`` in the frame, best score first, masks at the frame's size.

        A phrase longer than the text encoder's 32 tokens loses its last words (:func:`fit_phrase`); the detections
        still carry ``phrase`` as given.
        """
        height, width = observation.rgb.shape[:2]
        text = fit_phrase(self.processor.tokenizer, phrase, self.model.config.text_config.max_position_embeddings)
        batch = self.processor(images=Image.fromarray(observation.rgb), text=text, return_tensors="pt")
        outputs = run_model(self.model, batch)
        result = self.processor.post_process_instance_segmentation(
            outputs,
            threshold=self.score_threshold,
            mask_threshold=self.mask_threshold,
            target_sizes=[(height, width)],
        )[0]
        scores = result["scores"].float().cpu().numpy()
        masks = result["masks"].bool().cpu().numpy()
        return ranked_detections(scores, masks, phrase)
