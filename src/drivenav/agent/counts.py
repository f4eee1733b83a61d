"""The episode's decision counters while it runs, frozen into :class:`~drivenav.agent.base.DecisionStats` for its
record: labels the tracker created, merged and removed (Sec. IV-A b), inspection events and decisions by trigger
(Sec. IV-A c), steps by activity and turn reversals (oscillation)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from drivenav.agent.base import DecisionStats
from drivenav.types import Action

TURNS = (Action.TURN_LEFT, Action.TURN_RIGHT)


@dataclass
class EpisodeCounts:
    """The episode's :class:`~drivenav.agent.base.DecisionStats`, while it runs."""

    labels_created: int = 0
    labels_merged: int = 0
    labels_removed: int = 0
    inspection_events: int = 0
    decisions: Counter[str] = field(default_factory=Counter)
    dead_end_decisions: int = 0
    followed_through_relabel: int = 0
    selected_lost: int = 0
    labels_reidentified: int = 0
    steps: Counter[str] = field(default_factory=Counter)
    turn_reversals: int = 0
    last_turn: Action | None = None

    def count_step(self, action: Action, activity: str) -> None:
        """Count a step under ``activity``; a turn right after a turn the other way is a reversal."""
        self.steps[activity] += 1
        if action in TURNS and self.last_turn in TURNS and action != self.last_turn:
            self.turn_reversals += 1
        self.last_turn = action

    def freeze(self, candidates: int, accepted: int, set_aside: int) -> DecisionStats:
        """The counters with the target search's outcome (Sec. IV-C), for the episode's record."""
        return DecisionStats(
            labels_created=self.labels_created,
            labels_merged=self.labels_merged,
            labels_removed=self.labels_removed,
            inspection_events=self.inspection_events,
            decisions_by_reason=dict(sorted(self.decisions.items())),
            dead_end_decisions=self.dead_end_decisions,
            followed_through_relabel=self.followed_through_relabel,
            selected_lost=self.selected_lost,
            labels_reidentified=self.labels_reidentified,
            steps_by_activity=dict(sorted(self.steps.items())),
            turn_reversals=self.turn_reversals,
            target_candidates=candidates,
            targets_accepted=accepted,
            targets_set_aside=set_aside,
        )
