"""Persistent directions: speed field, weighted FMM paths, bearings, clustering, tracking (Sec. IV-A a-b)."""

from drivenav.directions.pipeline import DirectionPipeline
from drivenav.directions.tracking import DirectionTracker
from drivenav.directions.types import Cluster, Direction, DirectionResult, FrontierPath, TrackingUpdate

__all__ = [
    "Cluster",
    "Direction",
    "DirectionPipeline",
    "DirectionResult",
    "DirectionTracker",
    "FrontierPath",
    "TrackingUpdate",
]
