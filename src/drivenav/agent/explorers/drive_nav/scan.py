"""The start scan (paper Sec. IV overview): a 360 deg turn in place
(:class:`~drivenav.agent.explorers.full_scan.FullScan`) that records a representative view of every direction, then
a reasoner decision among them all. ``direction-360`` and ``frontier`` scan like this at every
decision point (``decision_scan``; Table II)."""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.decision import decide
from drivenav.agent.explorers.drive_nav.memory import Directions, Phase
from drivenav.agent.handles import StepHandles
from drivenav.types import Action, Observation


def act(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
    """Turn left until the scan's turns are done, then decide."""
    turn = d.scan.turn()
    if turn is not None:
        return turn
    return decide(d, handles, observation, ctx, "scan")


def start(d: Directions, handles: StepHandles) -> None:
    """Begin a full scan at a decision point (``decision_scan``)."""
    d.enter(handles, Phase.SCAN)
    d.scan.restart(handles)
