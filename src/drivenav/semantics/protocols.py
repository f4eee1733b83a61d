"""The two model interfaces of DRIVE-Nav: a reasoner (the VLM's role) and a grounder (the segmenter's role).

Backends (a geometric stand-in, the embedded world's ground-truth detector, and later real VLMs, SAM3, OWLv2)
implement these protocols; the agent only sees them. Positions and bearings are in the episode frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.base import Observation, Pose


@dataclass(frozen=True)
class View:
    """A representative view of a direction (Sec. IV-A c): the frame whose yaw was closest to its bearing.

    ``bearing`` is the direction's bearing when the view was taken and ``error`` = |yaw - bearing| then.
    ``semantic`` is the world's instance image where it has one (the embedded reasoner reads it).
    """

    label: int
    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    semantic: NDArray[np.int32] | None
    pose: Pose
    bearing: float
    error: float
    step: int


@dataclass(frozen=True)
class Candidate:
    """One option offered to the reasoner: a tracked direction (or a raw frontier in the frontier baseline).

    ``turn`` is the signed angle from the robot heading to ``bearing`` in ``(-pi, pi]``; ``travel_time`` the
    weighted-FMM time to its nearest frontier cell; ``frontier_cells`` how many frontier cells support it (its
    unexplored extent); ``view`` its representative view, if any.
    """

    label: int
    bearing: float
    turn: float
    travel_time: float
    frontier_cells: int
    view: View | None = None


@dataclass(frozen=True)
class Selection:
    """The reasoner's answer to "which direction next?" (Sec. IV-A c, IV-B).

    ``label`` is the chosen candidate (None: nothing worth exploring); ``target_visible`` and ``target_label``
    report whether and in which view the target appears; ``descriptions`` are short per-direction texts kept for
    prompt enrichment; ``fallback`` marks a deterministic fallback after a malformed answer.
    """

    label: int | None
    target_visible: bool = False
    target_label: int | None = None
    descriptions: Mapping[int, str] = field(default_factory=dict)
    fallback: bool = False
    note: str = ""


class Reasoner(Protocol):
    """Chooses among candidate directions from their representative views."""

    name: str

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection: ...


@dataclass(frozen=True)
class Detection:
    """One grounded instance of a phrase: a boolean mask over the image and a confidence in [0, 1]."""

    mask: NDArray[np.bool_]
    score: float
    phrase: str


class Grounder(Protocol):
    """Open-vocabulary segmentation of a phrase in the current frame (SAM3's role)."""

    name: str

    def segment(self, observation: Observation, phrase: str) -> list[Detection]: ...


SemanticLabels = Mapping[int, str]
"""What the world's instance ids mean (instance id -> category), as Habitat's semantic scene annotations."""
