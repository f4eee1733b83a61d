"""The paper's constants in one typed config (DRIVE-Nav, Sec. IV). Every default the paper states is the paper's
value; the few constants the paper leaves open are marked "ours" where they are declared (and listed in
docs/agent.md).

Angles are set in degrees (``*_deg`` fields, what a reader of the paper and of a YAML file expects) and read in
radians through the properties of the same name without the suffix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from drivenav.ranges import CELLS, COUNT, HALF_TURN, LENGTH, MAX_FACTOR, POSITIVE_LENGTH, STEPS, Range, check_ranges


@dataclass(frozen=True)
class SpeedFieldConfig:
    """Weighted FMM speed field F = F_obs * F_vor (Sec. IV-A a, Eqs. 1-3)."""

    lam: float = 0.65  # lambda in F_obs = 1 - lambda * exp(-d_obs / r_obs)
    r_obs: float = 0.8  # metres
    beta: float = 3.0  # beta in F_vor = 1 + beta * exp(-d_vor / r_vor)
    r_vor: float = 0.5  # metres
    weighted: bool = True  # False: uniform speed (ablation "w/o weighted FMM")
    skeleton_min_separation: float = 3.0  # ours: cells between the two nearest obstacles of a skeleton cell
    skeleton_min_angle_ratio: float = 1.3  # ours: |f(p) - f(q)| >= ratio * d (features subtend >= ~81 deg)

    def __post_init__(self) -> None:
        ranges = {
            "lam": Range(0.0, 1.0, high_open=True, why="lambda < 1: the speed field stays positive, Eq. 1"),
            "r_obs": POSITIVE_LENGTH,
            "beta": Range(0.0, MAX_FACTOR),
            "r_vor": POSITIVE_LENGTH,
            "skeleton_min_separation": CELLS,
            "skeleton_min_angle_ratio": Range(0.0, 2.0, why="2 sin(a / 2) of the angle a the features subtend"),
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class DirectionConfig:
    """Path-induced bearings, clustering and tracking (Sec. IV-A b)."""

    bearing_radius: float = 0.8  # R_e, metres
    cluster_span_deg: float = 45.0  # tau_theta
    path_bearings: bool = True  # False: straight-line bearing to the frontier (ablation)
    merge_tolerance: float = 0.25  # metres: frontier points "at the same world-frame location"
    association_gate_deg: float = 90.0  # ours: max Delta for an angular match
    source_snap_radius: float = 0.5  # ours: metres the FMM source may move to reach traversable space
    goal_snap_radius: float = 1.0  # ours: metres a goal point may move to reach traversable space
    margin_cells: float = 3.0  # ours: extra marching (cells at the slowest speed) after the last target

    def __post_init__(self) -> None:
        ranges = {
            "bearing_radius": POSITIVE_LENGTH,
            "cluster_span_deg": Range(0.0, 360.0, high_open=True, why="a circular gap, Sec. IV-A b"),
            "merge_tolerance": LENGTH,
            "association_gate_deg": HALF_TURN,
            "source_snap_radius": LENGTH,
            "goal_snap_radius": LENGTH,
            "margin_cells": CELLS,
        }
        check_ranges(self, ranges)

    @property
    def cluster_span(self) -> float:
        """tau_theta in radians."""
        return math.radians(self.cluster_span_deg)

    @property
    def association_gate(self) -> float:
        """The association gate in radians."""
        return math.radians(self.association_gate_deg)


@dataclass(frozen=True)
class InspectionConfig:
    """Representative views and the forward inspection range (Sec. IV-A c)."""

    forward_range_deg: float = 240.0  # directions with |alpha| <= 120 deg are inspectable
    view_tolerance_deg: float = 15.0  # a view is recorded once |yaw - bearing| < 15 deg
    restrict_forward: bool = True  # False: ablation "w/o 240 inspection view"

    def __post_init__(self) -> None:
        ranges = {
            "forward_range_deg": Range(0.0, 360.0, low_open=True, why="a sector of the circle"),
            "view_tolerance_deg": HALF_TURN,
        }
        check_ranges(self, ranges)

    @property
    def forward_range(self) -> float:
        """The forward inspection range in radians."""
        return math.radians(self.forward_range_deg)

    @property
    def view_tolerance(self) -> float:
        """The view tolerance in radians."""
        return math.radians(self.view_tolerance_deg)


@dataclass(frozen=True)
class SemanticsConfig:
    """Prompt enrichment and cross-frame verification (Sec. IV-B, IV-C)."""

    enrich_rounds: int = 5
    verify_frames: int = 3
    max_images_per_prompt: int = 30
    verify_spacing_steps: int = 3  # ours: steps between two verification frames of a candidate

    def __post_init__(self) -> None:
        ranges = {
            "enrich_rounds": STEPS,
            "verify_frames": COUNT,
            "max_images_per_prompt": COUNT,
            "verify_spacing_steps": STEPS,
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class DriveNavConfig:
    """All DRIVE-Nav constants, grouped by the paper's subsections."""

    speed: SpeedFieldConfig = field(default_factory=SpeedFieldConfig)
    directions: DirectionConfig = field(default_factory=DirectionConfig)
    inspection: InspectionConfig = field(default_factory=InspectionConfig)
    semantics: SemanticsConfig = field(default_factory=SemanticsConfig)
