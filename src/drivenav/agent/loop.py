"""The decision loop's dispatch on the mode (paper Sec. IV overview).

A :class:`Loop` is what a mode handler works with: the agent it acts for (step, trace, STOP, segments), the
agent's fixed :class:`Tuning`, the running :class:`~drivenav.agent.state.EpisodeState` and the handler of every mode
(:class:`Modes`). :meth:`Loop.policy` continues the current mode; a handler that switches mode within a step
(an inspection event, a decision that sees the target) hands the step on through it. The handlers themselves
live in :mod:`drivenav.agent.modes` and :mod:`drivenav.agent.greedy`; this module imports none of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from drivenav.agent.base import Agent
from drivenav.agent.config import AgentConfig
from drivenav.agent.context import StepContext
from drivenav.agent.state import EpisodeState, Mode
from drivenav.agent.trace import Trace
from drivenav.paper import DriveNavConfig
from drivenav.types import Action, Observation, SimConfig

Handler = Callable[["Loop", Observation, StepContext], Action]
"""A mode's step: the action it takes now."""
Approach = Callable[["Loop", Observation, StepContext], Action | None]
"""The approach's step: ``None`` when it gave its target up, and the step goes on in the mode it left for."""


@dataclass(frozen=True)
class Tuning:
    """The agent's fixed settings: the task's, the agent's switches and tuning, the paper's constants."""

    sim: SimConfig
    config: AgentConfig
    paper: DriveNavConfig

    @property
    def turn(self) -> float:
        """One turn action, in radians."""
        return math.radians(self.sim.turn_angle_deg)


@dataclass(frozen=True)
class Modes:
    """The handler of each mode. ``follow`` is DRIVE-Nav's direction following or the greedy baseline's."""

    scan: Handler
    sweep: Handler
    follow: Handler
    enrich: Handler
    approach: Approach

    def after_approach(self, mode: Mode) -> Handler:
        """The handler of ``mode`` once no approach acts this step. That is following, for the follow mode and
        for an approach that set its target aside for another one (that one is approached from the next step)."""
        handlers = {Mode.SCAN: self.scan, Mode.SWEEP: self.sweep, Mode.ENRICH: self.enrich}
        return handlers.get(mode, self.follow)


@dataclass
class Loop:
    """One step of the decision loop: the agent, its tuning, the episode and the mode handlers."""

    host: Agent
    tuning: Tuning
    state: EpisodeState
    modes: Modes

    @property
    def step(self) -> int:
        return self.host.step

    @property
    def trace(self) -> Trace:
        return self.host.trace

    def stop(self, reason: str) -> Action:
        """Issue STOP and record why (the agent's stop reason and trace)."""
        return self.host.stop(reason)

    def start_segment(self) -> None:
        """A new frontier-selection segment begins at this step (revisit metric, Sec. V-C)."""
        self.host.start_segment(self.host.step)

    def policy(self, observation: Observation, ctx: StepContext) -> Action:
        """Continue the current mode: approach the target while there is one, else scan, sweep, enrich or follow."""
        if self.state.mode is Mode.APPROACH:
            action = self.modes.approach(self, observation, ctx)
            if action is not None:
                return action
        return self.modes.after_approach(self.state.mode)(self, observation, ctx)
