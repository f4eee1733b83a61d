"""What DRIVE-Nav's explorer remembers in one episode (paper Sec. IV-A b-c), and its counters.

:class:`Phase` names the explorer's modes (Sec. IV overview): the start scan, the inspection sweep, following a
direction and prompt enrichment; the body's approach is the fifth. :class:`Directions` is the explorer's memory,
which the mode modules (:mod:`~drivenav.agent.explorers.drive_nav.scan` and its siblings) share.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

from drivenav.agent.explorers.drive_nav.config import DirectionsConfig
from drivenav.agent.explorers.full_scan import FullScan
from drivenav.agent.handles import StepHandles
from drivenav.directions import Direction
from drivenav.inspection import RepresentativeViews
from drivenav.semantics.protocols import View


class Phase(Enum):
    """The explorer's mode; its value names the steps spent in it (``steps_by_activity``)."""

    SCAN = "scan"
    SWEEP = "sweep"
    FOLLOW = "follow"
    ENRICH = "enrich"


@dataclass
class DirectionCounters:
    """How an episode's exploration went (Sec. IV-A b-c): direction labels the tracker created, merged and removed;
    inspection events; reasoner decisions by trigger (``scan``, ``inspection``, ``vanished``, ``stuck``); decisions
    at a dead end (no still-relevant direction in the forward 240 deg, so the rear range was offered); how often the
    followed direction was carried over a relabelling (``followed_through_relabel``) or lost its label with no
    successor (``selected_lost``); fresh labels recognised as a retired direction (removed, or merged away) back at
    its place (``labels_reidentified``). Beyond the paper, with ``skip_void_events``: inspection events that ended
    without a decision because every direction that started them was gone (``void_events``), and choices left with
    one direction whose view the reasoner had judged, made without it (``forced_choices``). The explorer counts
    into its memory's instance while the episode runs; :meth:`recorded` is what the record keeps."""

    labels_created: int = 0
    labels_merged: int = 0
    labels_removed: int = 0
    inspection_events: int = 0
    decisions: dict[str, int] = field(default_factory=dict)
    dead_end_decisions: int = 0
    followed_through_relabel: int = 0
    selected_lost: int = 0
    labels_reidentified: int = 0
    void_events: int = 0
    forced_choices: int = 0

    def recorded(self) -> DirectionCounters:
        """A copy for the record: decisions by trigger in name order (the order they first happened in depends
        on the episode)."""
        return replace(self, decisions=dict(sorted(self.decisions.items())))


@dataclass
class Directions:
    """One episode's directions, views and decision state.

    ``scan`` is the full scan under way or last made (the start scan, or a decision's with ``decision_scan``);
    ``inspected`` holds the labels an inspection event or decision has already covered, ``blacklist`` the directions
    that could not be followed (label -> step until which they are left out), ``selected`` the direction followed and
    ``followed`` that direction as of the previous step; ``previous`` holds the previous step's directions and ``gone``
    the retired ones with the step they went (Sec. IV-A b). ``event_heading`` is the heading when the current inspection
    event began (Sec. IV-A c) and ``event_labels`` the directions that started it. ``turning_back`` says whether the
    last decision's options lay behind the robot only (a dead end), ``returning`` whether the followed direction was
    chosen so and is followed toward its nearest frontier (``return_aware``). ``descriptions`` and ``enriched`` are the
    reasoner's words on each direction and the directions enrichment has run on (Sec. IV-B); ``judged`` the steps of the
    views the reasoner has been shown. ``born`` holds the step since which each live or recently retired direction has
    been tracked (:func:`settled`). With ``target_check``, ``view_scores`` holds the image-text score of each view's
    frame (by step) and ``checked`` the directions a promising view has started a decision for. ``counts`` are the
    episode's counters.
    """

    config: DirectionsConfig
    views: RepresentativeViews
    scan: FullScan
    phase: Phase = Phase.SCAN
    pending_yaws: list[float] = field(default_factory=list)
    inspected: set[int] = field(default_factory=set)
    blacklist: dict[int, int] = field(default_factory=dict)
    descriptions: dict[int, str] = field(default_factory=dict)
    enriched: set[int] = field(default_factory=set)
    judged: set[int] = field(default_factory=set)
    enrich_label: int | None = None
    selected: int | None = None
    followed: Direction | None = None
    previous: dict[int, Direction] = field(default_factory=dict)
    gone: dict[int, tuple[Direction, int]] = field(default_factory=dict)
    event_heading: float = 0.0
    turning_back: bool = False
    returning: bool = False
    event_labels: tuple[int, ...] = ()
    born: dict[int, int] = field(default_factory=dict)
    view_scores: dict[int, float] = field(default_factory=dict)
    checked: set[int] = field(default_factory=set)
    counts: DirectionCounters = field(default_factory=DirectionCounters)

    def enter(self, handles: StepHandles, phase: Phase) -> None:
        """Switch to ``phase``: the explorer acts from now on (an approach under way gives way to it)."""
        self.phase = phase
        handles.explore()

    def activity(self, escaping: bool) -> str:
        """The steps-by-activity name of the current mode: ``start_scan`` for the scan before the first decision,
        ``escape`` for collision recovery while following."""
        if self.phase is Phase.FOLLOW and escaping:
            return "escape"
        if self.phase is Phase.SCAN:
            return "scan" if self.counts.decisions else "start_scan"
        return str(self.phase.value)


def settled(d: Directions, step: int, label: int) -> bool:
    """Whether direction ``label`` has been tracked for ``settle_steps`` steps (ours, beyond the paper; always true in
    the paper's agent, whose ``settle_steps`` is 0): only a settled direction starts an inspection event or counts
    as covered by one. A piece of the followed direction's frontier that splits off for a step or two and merges
    back never gets there (docs/agent.md "Beyond the paper")."""
    return step - d.born.get(label, step) >= d.config.settle_steps


def unjudged(d: Directions, view: View | None) -> bool:
    """Whether ``view`` is one the reasoner has not been shown yet (None, no view, is nothing new)."""
    return view is not None and view.step not in d.judged
