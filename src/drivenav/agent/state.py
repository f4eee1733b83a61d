"""What the agent body knows in one episode (paper Sec. IV): made when the agent is reset, dropped when the episode
ends, so nothing carries over from one episode to the next.

:class:`BodyState` holds the maps and models every exploration method works with -- the mapper, the directions
pipeline (one weighted-FMM solve a step gives every frontier's path), the local planner, the reasoner and the target
search -- and the body's own decision state: the point the planner heads for, the target candidate approached and
whether the approach is on. Where to explore is the explorer's, whose per-episode memory is the explorer itself
(:class:`~drivenav.agent.explorer.Explorer`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from drivenav.agent.context import Point
from drivenav.agent.planner import LocalPlanner
from drivenav.agent.tally import BodyTally
from drivenav.agent.target import TargetSearch
from drivenav.directions import DirectionPipeline
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.semantics.protocols import CategoryHints, Reasoner
from drivenav.types import Action


@dataclass
class BodyState:
    """One episode's maps, models and body state.

    ``goal`` is the point the planner heads for (its path comes with each step's solve); ``target`` is the
    candidate approached (Sec. IV-C) and ``approaching`` whether the approach acts: a target appearing starts it,
    and the explorer entering one of its own modes ends it (the target is kept: it is approached again when it
    changes). ``detour_steps`` counts the approach's steps through frontiers toward a target beyond the map.
    ``hints`` is the reasoner's answer on the goal's category, where the body or the explorer reads it.
    """

    mapper: OccupancyMapper
    pipeline: DirectionPipeline
    planner: LocalPlanner
    reasoner: Reasoner
    search: TargetSearch
    goal: Point | None = None
    target: int | None = None
    approaching: bool = False
    detour_steps: int = 0
    counts: BodyTally = field(default_factory=BodyTally)
    hints: CategoryHints | None = None

    def activity(self, action: Action) -> str | None:
        """The body's name for this step's action (the steps-by-activity counter): ``stop``, or ``approach`` and
        ``escape`` (collision recovery) while approaching; None when the explorer's mode names it."""
        if action == Action.STOP:
            return "stop"
        if self.approaching:
            return "escape" if self.planner.escaping else "approach"
        return None
