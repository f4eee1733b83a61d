"""The body's counters while an episode runs, frozen into :class:`~drivenav.agent.base.BodyCounters` for its record:
steps by activity and turn reversals (oscillation). An explorer keeps its own counters
(:meth:`~drivenav.agent.explorer.Explorer.counters`)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from drivenav.agent.base import BodyCounters
from drivenav.types import Action

TURNS = (Action.TURN_LEFT, Action.TURN_RIGHT)


@dataclass
class BodyTally:
    """The episode's :class:`~drivenav.agent.base.BodyCounters`, while it runs."""

    steps: Counter[str] = field(default_factory=Counter)
    turn_reversals: int = 0
    last_turn: Action | None = None

    def count_step(self, action: Action, activity: str) -> None:
        """Count a step under ``activity``; a turn right after a turn the other way is a reversal."""
        self.steps[activity] += 1
        if action in TURNS and self.last_turn in TURNS and action != self.last_turn:
            self.turn_reversals += 1
        self.last_turn = action

    def freeze(self, candidates: int, accepted: int, set_aside: int) -> BodyCounters:
        """The counters with the target search's outcome (Sec. IV-C), for the episode's record."""
        return BodyCounters(
            steps_by_activity=dict(sorted(self.steps.items())),
            turn_reversals=self.turn_reversals,
            target_candidates=candidates,
            targets_accepted=accepted,
            targets_set_aside=set_aside,
        )
