"""The report's settings: which episodes get pictures, how many processes draw them, and the sizes of what the
pages show. Defaults follow issue 38 (the report in the browser): pictures for failures only, no detail beyond the
top-down map unless asked, so that a 10 x 200-episode ablation run is reported within a minute on 2 cores."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class PictureChoice(str, Enum):
    """Which episodes get a picture drawn when none exists yet (a picture already drawn is always shown)."""

    FAILURES = "failures"
    ALL = "all"
    NONE = "none"


@dataclass(frozen=True)
class ReportConfig:
    """How ``drivenav report`` builds its site."""

    pictures: PictureChoice = PictureChoice.FAILURES  # issue 38: "a flag to limit pictures to failures"
    max_pictures: int | None = None  # issue 38: "... or to N episodes" (per run; None: no limit)
    views: bool = False  # the full ``drivenav viz`` pictures: last decisions' views, start and end views (slower)
    workers: int = 2  # drawing and page processes (issue 38's goal is measured on 2 cores)
    plot_width: int = 640  # px, the per-step module timing plot
    plot_height: int = 160  # px
    plot_points: int = 240  # at most this many steps plotted (longer episodes are binned by their mean)
    rows_per_table: int = 200  # event rows shown per table on an episode page (the rest are in the trace file)
