"""VLFM's explorer (Yokoyama et al., ICRA 2024): its settings section ``explorer.vlfm`` and its registration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from drivenav.agent.config import CounterSpec, ExplorerEntry, Rule
from drivenav.mapping.value_map import ValueMapConfig
from drivenav.ranges import LENGTH, Range
from drivenav.types import SimConfig


@dataclass(frozen=True)
class VlfmConfig(ValueMapConfig):
    """VLFM's constants (its value map's and its frontier choice's, :class:`~drivenav.mapping.value_map.ValueMapConfig`)
    and the goal distance it shares with the greedy baseline (ours)."""

    min_goal_distance: float = 1.0  # metres: a new choice considers frontier points at least this far (all if none)

    RANGES: ClassVar[Mapping[str, Range]] = {**ValueMapConfig.RANGES, "min_goal_distance": LENGTH}


def within_reach(config: Any, sim: SimConfig) -> tuple[Rule, ...]:
    """The frontier radius within the sensor's reach: the value map holds only what frames saw (a larger disk costs
    memory for nothing, and a vast one more than the machine has)."""
    reach = f"at most sim.max_depth ({sim.max_depth:g} m): the value map holds what frames saw"
    return (("frontier_radius", config.frontier_radius <= sim.max_depth, reach),)


EXPLORER = ExplorerEntry(
    "vlfm",
    VlfmConfig,
    "drivenav.agent.explorers.vlfm.explorer:VlfmExplorer",
    "VLFM: value map from image-text scores, highest-value frontier",
    ("agent.enrich=false", "agent.verify=false"),
    within_reach,
    counters=(
        CounterSpec("new_choices", "new choices", column=False),
        CounterSpec("acyclic_fallbacks", "acyclic fallbacks", column=False),
        CounterSpec("goals_skipped", "goals skipped", column=False),
    ),
    activities=("start_scan", "follow", "escape"),
)
