"""The start scan (paper Sec. IV overview): a 360 deg turn in place that records a representative view of every
direction, then a reasoner decision among them all. ``direction-360`` and ``frontier`` scan like this at every
decision point (``decision_scan``; Table II)."""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.decision import decide
from drivenav.agent.loop import Loop
from drivenav.agent.state import Mode
from drivenav.agent.trace import ScanStarted
from drivenav.inspection import full_scan_turns
from drivenav.types import Action, Observation


def act(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """Turn left until the scan's turns are done, then decide."""
    state = loop.state
    if state.scan_turns > 0:
        state.scan_turns -= 1
        return Action.TURN_LEFT
    return decide(loop, observation, ctx, "scan")


def start(loop: Loop) -> None:
    """Begin a full scan at a decision point (``decision_scan``)."""
    state = loop.state
    state.mode, state.scan_turns = Mode.SCAN, full_scan_turns(loop.tuning.turn)
    loop.trace.add(ScanStarted(loop.step, state.scan_turns))
