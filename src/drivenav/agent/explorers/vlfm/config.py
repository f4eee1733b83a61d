"""VLFM's explorer (Yokoyama et al., ICRA 2024): its settings section ``explorer.vlfm`` and its registration."""

from __future__ import annotations

from dataclasses import dataclass

from drivenav.agent.config import ExplorerEntry
from drivenav.mapping.value_map import ValueMapConfig


@dataclass(frozen=True)
class VlfmConfig(ValueMapConfig):
    """VLFM's constants (its value map's and its frontier choice's, :class:`~drivenav.mapping.value_map.ValueMapConfig`)
    and the goal distance it shares with the greedy baseline (ours)."""

    min_goal_distance: float = 1.0  # metres: a new choice considers frontier points at least this far (all if none)


EXPLORER = ExplorerEntry(
    "vlfm",
    VlfmConfig,
    "drivenav.agent.explorers.vlfm.explorer:VlfmExplorer",
    "VLFM: value map from image-text scores, highest-value frontier",
    ("agent.enrich=false", "agent.verify=false"),
)
