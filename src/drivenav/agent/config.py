"""The agent body's own settings and how an exploration method registers itself: plain frozen dataclasses, so the
settings layer reads them without importing agent behaviour.

The body (:mod:`drivenav.agent.body`) does what every method shares -- mapping, grounding with enrichment and
cross-frame verification where switched on, the approach and STOP, collision recovery, segments -- with the tuning
of :class:`AgentConfig`; the paper's constants are :class:`~drivenav.paper.DriveNavConfig` beside it. Where to
explore next is an *explorer*'s (:mod:`drivenav.agent.explorer`), registered by an :class:`ExplorerEntry`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from drivenav.ranges import COUNT, LENGTH, POSITIVE_LENGTH, STEPS, UNIT, check_ranges, check_rule
from drivenav.types import SimConfig


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
class FusionConfig:
    """Target-centric semantic fusion (ApexNav, Zhang et al., RA-L 2025; code Robotics-STAR-Lab/ApexNav,
    ``object_map2d.cpp`` and ``map_ros.cpp``), the body's way of accepting detections when ``enabled``
    (:mod:`drivenav.agent.fusion`): every frame the target and the reasoner's confusable objects are detected as
    competing labels and fused per object, and an object becomes the target when the target's label leads, its
    fused confidence reaches the category's threshold and it was detected ``min_detections`` times. The
    constants are the code's (its launch file and sources); where our maps differ the docstrings of
    :mod:`~drivenav.agent.fusion` say how they are read."""

    enabled: bool = False
    min_detections: int = 2  # isConfidenceObject: n_obs of the target's label >= 2
    association_distance: float = 0.08  # searchSingleObjectCluster: a detection joins the first object with a ...
    # ... cell within 0.08 m of one of its cells
    count_voxel: float = 0.04  # detectedObjectCloudCallback: clouds voxelled at 0.04 m; a detection weighs ...
    # ... as many points as its voxels (here the 0.04 m cells of its footprint)
    max_range: float = 4.9  # detectedObjectCloudCallback: points farther than 4.9 m from the camera are dropped
    evidence_voxel: float = 0.1  # getObservationObjectsCloud: object and depth clouds voxelled at 0.1 m
    evidence_distance: float = 0.11  # inputObservationObjectsCloud: an object point with a depth point within ...
    # ... 0.11 m is in view; an object in view and not detected gets that many points of negative evidence
    goal_views: int = 4  # the goal cells of an object: seen as the target at least min(4, most seen) times
    suspicious_confidence: float = 0.01  # planNextBestPoint: with nothing left to explore, the object of highest ...
    # ... target confidence above 0.01 is approached even below the threshold

    def __post_init__(self) -> None:
        ranges = {
            "min_detections": COUNT,
            "association_distance": LENGTH,
            "count_voxel": POSITIVE_LENGTH,
            "max_range": LENGTH,
            "evidence_voxel": POSITIVE_LENGTH,
            "evidence_distance": LENGTH,
            "goal_views": COUNT,
            "suspicious_confidence": UNIT,
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class AgentConfig:
    """The body's switches (paper Table VI: ``enrich``, ``verify``) and its own tuning (ours: the paper does not give
    these); the paper's constants are a :class:`~drivenav.paper.DriveNavConfig` beside them and the exploration
    method's are its explorer's section (``explorer.<name>``)."""

    enrich: bool = True  # prompt enrichment (Sec. IV-B)
    verify: bool = True  # cross-frame verification (Sec. IV-C)
    stop_distance: float = 0.9  # metres from the target's nearest observed point within which to STOP ...
    # ... once the target is in the current frame (goal view points are positions that see the object).
    give_up_distance: float = 1.0  # a stuck approach this close to the target still STOPs
    blacklist_steps: int = 40  # steps a direction, frontier goal or target that could not be reached is left out
    replan_shift: float = 0.3  # metres the approach goal may move before this step's path is re-planned
    approach_detour_steps: int = 60  # steps an approach may go through frontiers before the target is set aside
    stop_in_view: bool = True  # STOP within stop_distance only with the target in the current frame (else at once)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)  # ApexNav's acceptance of detections (off: ours)

    def __post_init__(self) -> None:
        ranges = {
            "stop_distance": LENGTH,
            "give_up_distance": LENGTH,
            "blacklist_steps": STEPS,
            "replan_shift": LENGTH,
            "approach_detour_steps": STEPS,
        }
        check_ranges(self, ranges)
        expected = "false while agent.fusion.enabled is true (fused objects are accepted by fusion, not verified)"
        check_rule(self, "verify", not (self.verify and self.fusion.enabled), expected)


Rule = tuple[str, bool, str]
"""A rule between an explorer's section and the rest of the settings: the section's key, whether it holds, what the
key accepts."""


def no_rules(config: Any, sim: SimConfig) -> tuple[Rule, ...]:
    """An explorer whose section's ranges are all its own (checked where they are declared)."""
    return ()


@dataclass(frozen=True)
class ExplorerEntry:
    """An exploration method's registration (the object an entry point of group ``drivenav.explorers`` names).

    ``name`` is its settings section (``explorer.<name>``) and the value of ``explorer.name`` that picks it;
    ``config`` the frozen dataclass of that section, whose defaults are the method's source's constants;
    ``explorer`` the ``module:Class`` of its :class:`~drivenav.agent.explorer.Explorer`, imported when an agent is
    built; ``body`` the dotted overrides of the body's switches its method preset sets (``agent.enrich=false``);
    ``rules`` the rules its section must keep with the rest of the settings (given the section and ``sim``; the
    section's own ranges are checked by its dataclass, :mod:`drivenav.ranges`). A plug-in explorer is also an
    ``--agent`` name: its own method, ``explorer.name=<name>`` plus ``body``.
    """

    name: str
    config: type
    explorer: str
    description: str
    body: tuple[str, ...] = ()
    rules: Callable[[Any, SimConfig], tuple[Rule, ...]] = no_rules
