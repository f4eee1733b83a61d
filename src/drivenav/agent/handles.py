"""One step of the decision loop (paper Sec. IV overview): the body's approach first, else the explorer.

:class:`StepHandles` are one step's handles, what the body's approach and an explorer's modes work with: the agent
they act for (step, trace, STOP, segments), the agent's fixed :class:`Tuning`, the running
:class:`~drivenav.agent.state.BodyState`, the episode's explorer and the body's approach.
:meth:`StepHandles.policy` approaches the target while the approach is on; otherwise, or when the approach gave its
target up this step, the explorer acts. A mode that switches mode within a step (an inspection event, a decision
that sees the target) hands the step on through :meth:`StepHandles.policy`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivenav.agent.base import Agent
from drivenav.agent.config import AgentConfig
from drivenav.agent.context import StepContext
from drivenav.agent.state import BodyState
from drivenav.agent.trace import Trace
from drivenav.paper import DriveNavConfig
from drivenav.types import Action, Observation, SimConfig

if TYPE_CHECKING:
    from drivenav.agent.explorer import Explorer

Approach = Callable[["StepHandles", Observation, StepContext], Action | None]
"""The approach's step: ``None`` when it gave its target up, and the step goes on with the explorer."""


@dataclass(frozen=True)
class Tuning:
    """The agent's fixed settings: the task's, the body's switches and tuning, the paper's constants."""

    sim: SimConfig
    config: AgentConfig
    paper: DriveNavConfig

    @property
    def turn(self) -> float:
        """One turn action, in radians."""
        return math.radians(self.sim.turn_angle_deg)


@dataclass
class StepHandles:
    """One step's handles: the agent, its tuning, the episode's body state and explorer, the approach."""

    host: Agent
    tuning: Tuning
    state: BodyState
    explorer: Explorer
    approach: Approach

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

    def explore(self) -> None:
        """The explorer takes over from the approach (it entered one of its modes); the target is kept."""
        self.state.approaching = False

    def policy(self, observation: Observation, ctx: StepContext) -> Action:
        """Approach the target while the approach is on, else (or once it gave its target up) explore."""
        if self.state.approaching:
            action = self.approach(self, observation, ctx)
            if action is not None:
                return action
        return self.explorer.act(self, observation, ctx)
