"""The agent's own settings: the switches that compose DRIVE-Nav and its baselines, and the tuning the paper does
not give (the paper's constants are :class:`~drivenav.paper.DriveNavConfig`). Plain frozen dataclasses, so the
settings layer reads them without importing the agent (VLFM's constants come from the value map's module, which
needs only numpy and the grid)."""

from __future__ import annotations

from dataclasses import dataclass, field

from drivenav.mapping.value_map import ValueMapConfig
from drivenav.ranges import COUNT, LENGTH, POSITIVE_LENGTH, STEPS, check_ranges


@dataclass(frozen=True)
class PlannerConfig:
    """The local planner's tuning (ours: the paper names a low-level planner but not its parameters)."""

    lookahead: float = 0.8  # metres: radius of the pursuit circle
    stuck_steps: int = 16  # forward steps over which progress is measured
    stuck_progress: float = 0.15  # metres of net progress below which those steps count as stuck
    escape_turns: int = 2  # turns per blocked forward step in a row before the escape step
    max_turns: int = 12  # turns in a row after which the planner reports spinning

    def __post_init__(self) -> None:
        ranges = {
            "lookahead": POSITIVE_LENGTH,
            "stuck_steps": COUNT,
            "stuck_progress": LENGTH,
            "escape_turns": COUNT,
            "max_turns": COUNT,
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class AgentConfig:
    """Switches composing DRIVE-Nav and its baselines (paper Tables II, V, VI), and the agent's own tuning (ours:
    the paper does not give these); the paper's constants are a :class:`~drivenav.paper.DriveNavConfig` beside
    them. ``value_map`` makes the ``use_reasoner=False`` baseline VLFM (``vlfm``), whose constants are ``vlfm``."""

    use_reasoner: bool = True  # False: greedy nearest frontier, no views, no reasoner
    value_map: bool = False  # with use_reasoner False: VLFM's value map and highest-value frontier (agent/vlfm.py)
    enrich: bool = True  # prompt enrichment (Sec. IV-B)
    verify: bool = True  # cross-frame verification (Sec. IV-C)
    decision_scan: bool = False  # True: a full 360 deg scan at every decision point
    stop_distance: float = 0.9  # metres from the target's nearest observed point within which to STOP ...
    # ... once the target is in the current frame (goal view points are positions that see the object).
    give_up_distance: float = 1.0  # a stuck approach this close to the target still STOPs
    blacklist_steps: int = 40  # steps a direction (or greedy goal) that could not be followed is left out
    min_goal_distance: float = 1.0  # greedy baseline: frontier points nearer than this (metres) are not goals
    replan_shift: float = 0.3  # metres the approach goal may move before this step's path is re-planned
    reidentify_steps: int = 500  # steps a removed direction is remembered, to recognise it under a fresh label
    approach_detour_steps: int = 60  # steps an approach may go through frontiers before the target is set aside
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    vlfm: ValueMapConfig = field(default_factory=ValueMapConfig)  # VLFM's constants (Yokoyama et al., ICRA 2024)

    def __post_init__(self) -> None:
        ranges = {
            "stop_distance": LENGTH,
            "give_up_distance": LENGTH,
            "blacklist_steps": STEPS,
            "min_goal_distance": LENGTH,
            "replan_shift": LENGTH,
            "reidentify_steps": STEPS,
            "approach_detour_steps": STEPS,
        }
        check_ranges(self, ranges)
