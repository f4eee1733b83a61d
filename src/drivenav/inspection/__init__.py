"""Representative views and forward-240 deg inspection sweeps (DRIVE-Nav Sec. IV-A c)."""

from drivenav.inspection.sweep import (
    ANGLE_EPS,
    full_scan_turns,
    plan_sweep,
    signed_offset,
    sweep_turns,
    turn_toward,
    within,
)
from drivenav.inspection.views import RepresentativeViews, needs_inspection

__all__ = [
    "ANGLE_EPS",
    "RepresentativeViews",
    "full_scan_turns",
    "needs_inspection",
    "plan_sweep",
    "signed_offset",
    "sweep_turns",
    "turn_toward",
    "within",
]
