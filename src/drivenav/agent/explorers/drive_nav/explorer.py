"""DRIVE-Nav's explorer (``explorer.name=directions``; paper Sec. IV overview, IV-A): persistent directions,
representative views, inspection events and one reasoner decision among the still-relevant directions.

Each step, after the body's solve has turned the frontiers into tracked directions (Sec. IV-A a-b), the explorer
carries what belongs to each direction over its relabelling (:mod:`~drivenav.agent.explorers.drive_nav.relabel`)
and records a representative view of every direction the camera now faces better than before (Sec. IV-A c). Then
it continues its mode, each in a module of this package:

- ``SCAN``: the 360 deg start scan (twelve 30 deg turns), then a reasoner decision
  (:mod:`~drivenav.agent.explorers.drive_nav.scan`);
- ``SWEEP``: an inspection event -- rotate only over the forward-240 deg directions lacking views, then decide
  (:mod:`~drivenav.agent.explorers.drive_nav.sweep`);
- ``FOLLOW``: drive toward the farthest frontier point of the selected direction (re-planned each step) until an
  inspection event or the direction is gone (:mod:`~drivenav.agent.explorers.drive_nav.follow`);
- ``ENRICH``: the reasoner sees the target but the grounder does not: face that direction, then prompt enrichment
  (Sec. IV-B; :mod:`~drivenav.agent.explorers.drive_nav.enrich`).

Which directions a decision offers the reasoner is :mod:`~drivenav.agent.explorers.drive_nav.decision`'s
(docs/agent.md). ``decision_scan`` (a full 360 deg scan at every decision) gives ``direction-360`` and, with raw
frontiers as candidates (``paper.directions.cluster_span_deg=0``), ``frontier``; the speed field's ``weighted``
flag and the inspection's ``restrict_forward`` flag give the ablations of Table V.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivenav.agent.context import StepContext
from drivenav.agent.explorer import Explorer, ExplorerSetup
from drivenav.agent.explorers.drive_nav import enrich, follow, scan, sweep
from drivenav.agent.explorers.drive_nav.config import DirectionsConfig
from drivenav.agent.explorers.drive_nav.memory import DirectionCounters, Directions, Phase
from drivenav.agent.explorers.drive_nav.relabel import carry_over
from drivenav.agent.explorers.full_scan import FullScan
from drivenav.agent.handles import StepHandles
from drivenav.agent.trace import ViewCaptured
from drivenav.inspection import RepresentativeViews
from drivenav.semantics.protocols import ImageTextScorer, ModelCall
from drivenav.types import Action, Observation

Mode = Callable[[Directions, StepHandles, Observation, StepContext], Action]

MODES: dict[Phase, Mode] = {
    Phase.SCAN: scan.act,
    Phase.SWEEP: sweep.act,
    Phase.FOLLOW: follow.act,
    Phase.ENRICH: enrich.act,
}
"""Each mode's step."""


def begin_directions(setup: ExplorerSetup, config: DirectionsConfig) -> Directions:
    """An episode's empty directions memory, its start scan ahead (twelve 30 deg turns)."""
    views = RepresentativeViews(setup.tuning.paper.inspection.view_tolerance)
    return Directions(config, views, FullScan.ahead(setup.tuning))


class DirectionsExplorer(Explorer):
    """DRIVE-Nav's exploration (module docstring)."""

    def __init__(self, setup: ExplorerSetup) -> None:
        if not isinstance(setup.config, DirectionsConfig):
            raise TypeError(f"the directions explorer takes a DirectionsConfig, not {type(setup.config).__name__}")
        self.memory = begin_directions(setup, setup.config)
        self.scorer: ImageTextScorer | None = setup.scorer  # given only when needs_scorer says so
        if self.scorer is not None:
            self.scorer.begin_episode(setup.truth)

    @classmethod
    def needs_scorer(cls, config: object) -> bool:
        """Only with the target check (``target_check``, beyond the paper): the paper's agent loads no scorer."""
        return isinstance(config, DirectionsConfig) and config.target_check > 0.0

    def begin(self, handles: StepHandles) -> None:
        self.memory.scan.begin(handles)

    def observe(
        self, handles: StepHandles, observation: Observation, ctx: StepContext, timings: dict[str, float]
    ) -> None:
        """Carry each direction's state over its relabelling, then record representative views (timed together as
        ``inspection``)."""
        start = time.perf_counter()
        carry_over(self.memory, handles, ctx)
        if record_views(self.memory, handles, observation, ctx) and self.scorer is not None:
            self.memory.view_scores[handles.step] = self.scorer.score(handles.host.goal_text, observation)
        timings["inspection"] = (time.perf_counter() - start) * 1000.0

    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        return MODES[self.memory.phase](self.memory, handles, observation, ctx)

    def resume(self, handles: StepHandles) -> None:
        """Back to the followed direction once the approach gives its target up (a decision if it is gone)."""
        self.memory.enter(handles, Phase.FOLLOW)

    def activity(self, escaping: bool) -> str:
        return self.memory.activity(escaping)

    def counters(self) -> DirectionCounters:
        return self.memory.counts.recorded()

    def model_calls(self) -> list[ModelCall]:
        return list(self.scorer.calls) if self.scorer is not None else []


def record_views(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext) -> bool:
    """Keep the views of live and recently retired directions, and record a view of every direction the camera now
    faces better than before (Sec. IV-A c); True if this frame became a view."""
    d.views.retain([*ctx.directions, *d.gone])
    written = d.views.observe(ctx.result.directions, observation, handles.step)
    for label, updated in written:
        view = d.views.get(label)
        if view is not None:
            handles.trace.add(ViewCaptured(handles.step, label, view.pose.yaw, view.error, updated))
    return bool(written)
