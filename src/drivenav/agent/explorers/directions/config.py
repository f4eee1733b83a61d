"""DRIVE-Nav's explorer (paper Sec. IV-A): its settings section ``explorer.directions`` and its registration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.config import ExplorerEntry
from drivenav.ranges import STEPS, UNIT, Range, check_declared


@dataclass(frozen=True)
class DirectionsConfig:
    """The directions explorer's switches and tuning; the paper's constants it reads are ``paper.directions`` and
    ``paper.inspection`` (:class:`~drivenav.paper.DriveNavConfig`).

    The switches after ``reidentify_steps`` go beyond the paper (the ``drive-nav-plus`` method, docs/agent.md
    "Beyond the paper"); each is off by default, so ``drive-nav`` and every other method is the paper's agent.
    """

    decision_scan: bool = False  # True: a full 360 deg scan at every decision point (Table II: direction-360)
    reidentify_steps: int = 500  # ours: steps a removed direction is remembered, to recognise it under a fresh label
    skip_void_events: bool = False  # no reasoner question with nothing new to judge: a void event, a forced choice
    return_aware: bool = False  # a turn back finishes the near remainder of the chosen direction first
    settle_steps: int = 0  # steps a direction is tracked before it may start an inspection event (0: the paper's)
    target_check: float = 0.0  # image-text score of a new view at which it is judged at once (0: no check)

    RANGES: ClassVar[Mapping[str, Range]] = {"reidentify_steps": STEPS, "settle_steps": STEPS, "target_check": UNIT}

    def __post_init__(self) -> None:
        check_declared(self)


EXPLORER = ExplorerEntry(
    "directions",
    DirectionsConfig,
    "drivenav.agent.explorers.directions.explorer:DirectionsExplorer",
    "DRIVE-Nav: persistent directions, inspection events, one reasoner decision among the forward directions",
)
