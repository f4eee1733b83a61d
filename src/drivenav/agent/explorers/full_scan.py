"""The full 360 deg turn in place that every built-in explorer opens its episode with (the start scan, paper Sec. IV
overview: twelve 30 deg left turns) and that ``direction-360`` repeats at every decision.

While the robot turns, the body maps every frame and the target search looks through it, so the explorer chooses
its first goal on a map all around the robot. :class:`FullScan` counts the turns down; an explorer that explores its
own way once the scan is over (VLFM, ApexNav, a plug-in) calls :meth:`FullScan.act` first in its ``act`` and takes
over when it gives ``None``, and names its steps by :meth:`FullScan.activity`.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivenav.agent.handles import StepHandles, Tuning
from drivenav.agent.trace import ScanStarted
from drivenav.inspection import full_scan_turns
from drivenav.types import Action

START_SCAN = "start_scan"
"""The steps-by-activity name of the start scan's turns."""


@dataclass
class FullScan:
    """One full scan: the left turns still to make (``turns``) and whether it is over (``over``: the explorer acts
    from then on)."""

    turns: int
    over: bool = False

    @classmethod
    def ahead(cls, tuning: Tuning) -> FullScan:
        """A scan not started yet: as many turns of ``tuning.turn`` as make 360 deg (twelve of 30 deg)."""
        return cls(full_scan_turns(tuning.turn))

    def begin(self, handles: StepHandles) -> None:
        """The start scan is announced in the trace (a ``scan`` event at this step: 0 for the episode's, the step
        of arrival for a floor first reached), from the explorer's ``begin``."""
        handles.trace.add(ScanStarted(handles.step, self.turns))

    def restart(self, handles: StepHandles) -> None:
        """A new full scan from this step (``direction-360``'s scan at a decision), announced in the trace."""
        self.turns, self.over = full_scan_turns(handles.tuning.turn), False
        handles.trace.add(ScanStarted(handles.step, self.turns))

    def turn(self) -> Action | None:
        """The scan's next turn (``TURN_LEFT``), or None once every turn is made."""
        if self.turns <= 0:
            return None
        self.turns -= 1
        return Action.TURN_LEFT

    def act(self, handles: StepHandles) -> Action | None:
        """The scan's next turn, or None when the scan is over (the step after its last turn ends it): the
        explorer's own exploring acts then."""
        if self.over:
            return None
        action = self.turn()
        if action is None:
            self.end(handles)
        return action

    def end(self, handles: StepHandles) -> None:
        """The scan is over, done or cut short (an explorer's ``resume``: the approach took over mid-scan and gave its
        target up): the explorer acts from now on."""
        self.over = True
        handles.explore()

    def activity(self, escaping: bool) -> str:
        """The steps-by-activity name of an explorer that scans and then follows goals: ``start_scan`` during the
        scan, then ``follow``, or ``escape`` while the planner recovers from a collision."""
        if not self.over:
            return START_SCAN
        return "escape" if escaping else "follow"
