"""The served grounder's settings (``drivenav serve grounder``), apart from its server so that the command line
reads them without loading numpy or zmq."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

DEFAULT_BIND: Final[str] = "tcp://127.0.0.1:5557"
"""``serve grounder``'s default endpoint (the robot's is 5555) and ``models.detector_url``'s."""
MAX_BATCH: Final[int] = 256
"""The most frames a batch may wait for (``--batch``): every one of them is held in memory until the batch runs."""
MAX_BATCH_MS: Final[float] = 1000.0
"""The longest a request may wait for its batch to fill (``--batch-ms``): a second on every frame of every episode
already makes a 500-step episode eight minutes slower, and a client's request must be answered well within its
``models.detector_timeout_s``."""
MAX_COPIES: Final[int] = 8
"""The most copies of a model one server runs (``--copies``): each holds its weights and activations on the device."""
LABEL_BYTES: Final[int] = 192
"""What one ground-truth label of a stand-in's episode is charged (measured: about 185 bytes a label in the
ground-truth stand-in, 115 in the embedded one, CPython 3.11)."""
ENTRY_BYTES: Final[int] = 128
"""What a label name or a phrase of a stand-in's vocabulary is charged, besides its characters."""
DEFAULT_MAX_DETECTIONS: Final[int] = 200
"""The detections a frame kept by default, the best scores (``models.max_detections`` and the server's
``max_detections``; :mod:`drivenav.semantics.checked`): SAM3's 200 object queries, the most any built-in grounder
returns (the box detectors keep :data:`~drivenav.semantics.boxes.MAX_BOXES`)."""
MAX_DETECTIONS: Final[int] = 10_000
"""The largest ``models.max_detections``: each detection costs the agent a pass over the frame, and ten thousand
full-frame masks take minutes a step."""


@dataclass(frozen=True)
class ServeConfig:
    """The server's batching and limits: a batch runs at ``batch`` frames or when its oldest request has waited
    ``batch_ms`` (ours: 8 is issue 37's batch, 33 ms a frame for SAM3 in bf16 on an H100 against 62-103 ms alone;
    5 ms is a small fraction of one forward); ``phrases`` phrases' text features are kept. Frames are limited as the
    robot protocol's are (``MAX_ARRAY_BYTES``).

    What a stand-in's episodes hold is bounded: a BEGIN carries at most ``labels`` labels (more is an ERROR reply);
    one client (one connection) keeps at most ``client_episodes`` episodes and ``client_bytes`` bytes of them, all
    clients together ``episodes`` and ``held_bytes``; past a bound the least recently used episodes are forgotten,
    the client's own first (a client grounds one episode at a time, and never ends one: it begins the next). An
    episode's vocabulary grows by at most ``phrases`` phrases. Bytes are charged as :data:`LABEL_BYTES` a label and
    :data:`ENTRY_BYTES` (and its characters) a name or phrase. A frame's reply holds at most ``max_detections``
    detections, checked as in process (:mod:`drivenav.semantics.checked`). A model (not a stand-in) runs as
    ``copies`` copies, each in a thread of its own (one fills a GPU only when its batches keep it busy). A batch
    also runs, before ``batch_ms``, once every client that sent a frame in the last ``active_s`` seconds has one
    queued or in the model: a client waits for its reply before its next frame, so none can come (a worker that
    grounds every step, or every few seconds behind a VLM's answer, is such a client). A frame whose SEGMENTs its
    client sent at once (``together``) waits for all of them, at most ``parts_s`` after the first came: a batch that
    took it in parts would leave the rest to a later batch and encode the frame twice.
    """

    batch: int = 8
    batch_ms: float = 5.0
    episodes: int = 1024
    phrases: int = 1024
    poll_ms: int = 100
    labels: int = 65_536
    client_episodes: int = 8
    client_bytes: int = 128 * 2**20
    held_bytes: int = 2**30
    max_detections: int = DEFAULT_MAX_DETECTIONS
    copies: int = 1
    active_s: float = 10.0
    parts_s: float = 1.0

    def __post_init__(self) -> None:
        for name, seconds in (("active_s", self.active_s), ("parts_s", self.parts_s)):
            if not (math.isfinite(seconds) and seconds > 0.0):
                raise ValueError(f"{name} must be a positive number of seconds, got {seconds}")
        if not 1 <= self.copies <= MAX_COPIES:
            raise ValueError(f"copies must be 1-{MAX_COPIES}, got {self.copies}")
        if not 1 <= self.batch <= MAX_BATCH:
            raise ValueError(f"batch must be 1-{MAX_BATCH}, got {self.batch}")
        if not (math.isfinite(self.batch_ms) and 0.0 <= self.batch_ms <= MAX_BATCH_MS):
            raise ValueError(f"batch_ms must be 0-{MAX_BATCH_MS:g}, got {self.batch_ms}")
        counts = (self.episodes, self.phrases, self.poll_ms, self.labels, self.client_episodes, self.max_detections)
        if min(counts) < 1 or self.client_bytes < self.labels * LABEL_BYTES or self.held_bytes < self.client_bytes:
            raise ValueError(f"limits must be >= 1, and held_bytes >= client_bytes >= labels * {LABEL_BYTES}: {self}")


def takes_model_options(detector: str) -> bool:
    """Whether the served ``detector`` honours the model options (``--detector-model``, ``--device``, ``--dtype``,
    ``--compile``, ``--segmenter``, ``--segmenter-model``): a transformers model detector, or a plug-in's grounder
    (its builder reads them from the models' settings). The embedded and ground-truth stand-ins load no model:
    ``serve grounder`` refuses those options with them, and ``eval --share-detector`` gives none."""
    from drivenav.semantics.registry import GROUNDER_BACKENDS, MODEL_DETECTORS

    return detector in MODEL_DETECTORS or GROUNDER_BACKENDS.is_plugin(detector)
