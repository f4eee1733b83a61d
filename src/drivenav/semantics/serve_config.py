"""The served grounder's settings (``drivenav serve grounder``), apart from its server so that the command line
reads them without loading numpy or zmq."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

DEFAULT_BIND: Final[str] = "tcp://127.0.0.1:5557"
"""``serve grounder``'s default endpoint (the robot's is 5555) and ``models.detector_url``'s."""


@dataclass(frozen=True)
class ServeConfig:
    """The server's batching and limits: a batch runs at ``batch`` frames or when its oldest request has waited
    ``batch_ms`` (ours: 8 is issue 37's batch, 33 ms a frame for SAM3 in bf16 on an H100 against 62-103 ms alone;
    5 ms is a small fraction of one forward); ``episodes`` stand-in episodes and ``phrases`` phrases' text features
    are kept. Frames are limited as the robot protocol's are (``MAX_ARRAY_BYTES``)."""

    batch: int = 8
    batch_ms: float = 5.0
    episodes: int = 1024
    phrases: int = 1024
    poll_ms: int = 100

    def __post_init__(self) -> None:
        if self.batch < 1 or not self.batch_ms >= 0.0:
            raise ValueError(f"batch must be >= 1 and batch_ms >= 0, got {self.batch} and {self.batch_ms}")
