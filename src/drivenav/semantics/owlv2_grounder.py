"""OWLv2 boxes turned into masks: the grounding backbone DRIVE-Nav is compared against (paper Sec. V-D).

The paper's comparison pairs OWLv2 (text-conditioned open-vocabulary boxes) with MobileSAM (box-prompted masks),
as VLFM does. Through transformers: ``Owlv2Processor`` (image + one text query) -> ``Owlv2ForObjectDetection``
-> ``post_process_grounded_object_detection`` gives scored boxes in frame pixels (the processor pads the frame to
a square, so boxes may reach past its bottom or right edge); a :class:`BoxSegmenter` then turns each box into a
mask. MobileSAM is not packaged here, so the default segmenter is :class:`FilledBoxSegmenter`: the box itself
filled, which over-covers the object but keeps the object's position and extent.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from drivenav.semantics.hf_common import fit_phrase, load_pair, pick_device, ranked_detections, run_model
from drivenav.semantics.protocols import Detection
from drivenav.types import GroundTruth, Observation

OWLV2_EXPECTED = "a local OWLv2 checkpoint directory or a model id in the Hugging Face cache"


class BoxSegmenter(Protocol):
    """Box-prompted segmentation (MobileSAM's role in Sec. V-D).

    ``boxes`` is ``(N, 4)`` pixel corners ``(x0, y0, x1, y1)``, possibly reaching past the frame; the answer is
    ``(N, H, W)`` bool masks over the ``(H, W, 3)`` frame, one per box.
    """

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]: ...


class FilledBoxSegmenter:
    """The fallback :class:`BoxSegmenter`: a pixel belongs to a box's mask when its centre lies inside the box."""

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
        height, width = rgb.shape[:2]
        rows = np.arange(height) + 0.5
        cols = np.arange(width) + 0.5
        x0, y0, x1, y1 = (boxes[:, k, None] for k in range(4))
        inside_rows = (rows >= y0) & (rows < y1)
        inside_cols = (cols >= x0) & (cols < x1)
        masks: NDArray[np.bool_] = inside_rows[:, :, None] & inside_cols[:, None, :]
        return masks


class Owlv2Grounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with an OWLv2 checkpoint and a box segmenter.

    ``model`` is a checkpoint directory or a cached model id (never downloaded). Boxes scoring strictly above
    ``score_threshold`` are kept (0.1 is the transformers default for OWLv2). ``model_obj`` / ``processor_obj``
    inject already-built objects instead of loading; ``segmenter`` defaults to :class:`FilledBoxSegmenter`.
    """

    name = "owlv2"

    def __init__(
        self,
        model: str | Path = "google/owlv2-base-patch16-ensemble",
        device: str | None = None,
        score_threshold: float = 0.1,
        *,
        model_obj: Any = None,
        processor_obj: Any = None,
        segmenter: BoxSegmenter | None = None,
    ) -> None:
        from transformers import Owlv2ForObjectDetection, Owlv2Processor

        loaded, self.processor = load_pair(
            Owlv2ForObjectDetection.from_pretrained,
            Owlv2Processor.from_pretrained,
            model,
            OWLV2_EXPECTED,
            model_obj,
            processor_obj,
        )
        self.model = loaded.to(pick_device(device)).eval()
        self.score_threshold = score_threshold
        self.segmenter: BoxSegmenter = segmenter if segmenter is not None else FilledBoxSegmenter()

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Nothing to reset: OWLv2 grounds every frame independently and deterministically."""

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        """One detection per box of ``phrase`` with a non-empty mask, best score first.

        A phrase longer than the text encoder's 16 tokens loses its last words (:func:`fit_phrase`); the detections
        still carry ``phrase`` as given.
        """
        rgb = observation.rgb
        height, width = rgb.shape[:2]
        text = fit_phrase(self.processor.tokenizer, phrase, self.model.config.text_config.max_position_embeddings)
        batch = self.processor(images=Image.fromarray(rgb), text=[text], return_tensors="pt")
        outputs = run_model(self.model, batch)
        result = self.processor.post_process_grounded_object_detection(
            outputs, threshold=self.score_threshold, target_sizes=[(height, width)]
        )[0]
        scores = result["scores"].float().cpu().numpy()
        boxes = result["boxes"].float().cpu().numpy()
        masks = self.segmenter.segment_boxes(rgb, boxes)
        if masks.shape != (len(boxes), height, width):
            raise ValueError(
                f"box segmenter returned masks of shape {masks.shape}, expected {(len(boxes), height, width)}"
            )
        return ranked_detections(scores, masks, phrase)
