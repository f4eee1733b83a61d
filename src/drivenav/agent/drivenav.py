"""The DRIVE-Nav agent (paper Sec. IV overview), composable into its baselines.

Each step: depth + pose update the maps; one weighted-FMM solve turns frontiers into tracked directions and
gives the path to the current goal (Sec. IV-A a-b); labels carried over their relabelling keep what belongs to
their direction (:mod:`~drivenav.agent.relabel`); representative views are recorded opportunistically (Sec.
IV-A c); the grounder looks for the target (Sec. IV-B, IV-C). The policy then continues the current mode, each
in a module of :mod:`drivenav.agent.modes`:

- ``SCAN``: the 360 deg start scan (twelve 30 deg turns), then a reasoner decision;
- ``SWEEP``: an inspection event -- rotate only over the forward-240 deg directions lacking views, then decide;
- ``FOLLOW``: drive toward the farthest frontier point of the selected direction (re-planned each step) until an
  inspection event (new forward directions lacking views) or the direction is gone; a followed direction that
  only got a fresh label (merged with another, or re-found at the same place) is still followed;
- ``ENRICH``: the reasoner sees the target but the grounder does not: face that direction, then prompt
  enrichment (Sec. IV-B);
- ``APPROACH``: drive to the target candidate, verifying it on the way (Sec. IV-C), and STOP within
  ``stop_distance`` once it is accepted. While no mapped free cell leads to it yet, drive through the frontier
  nearest to it; a target that cannot be reached is set aside for a while, never rejected.

Which directions a decision offers the reasoner is :mod:`~drivenav.agent.decision`'s (docs/agent.md).

Config switches give the baselines and ablations: ``use_reasoner=False`` (the greedy nearest frontier,
:mod:`~drivenav.agent.greedy`; with ``value_map`` VLFM, :mod:`~drivenav.agent.vlfm`, which scores every frame with
an image-text scorer and spreads the score over a value map, :mod:`~drivenav.mapping.value_map`),
``decision_scan`` (a full 360 deg scan at every decision: ``direction-360``, ``frontier``), ``cluster_span`` 0
(raw frontiers as candidates), the speed field's ``weighted`` flag and the inspection's ``restrict_forward`` flag.

An episode's state is one :class:`~drivenav.agent.state.EpisodeState`, made by :meth:`DriveNavAgent.reset` and
dropped by :meth:`DriveNavAgent.end_episode`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivenav.agent import greedy, vlfm
from drivenav.agent.base import Agent, DecisionStats, ModelStats
from drivenav.agent.config import AgentConfig
from drivenav.agent.context import StepContext, perceive
from drivenav.agent.loop import Loop, Modes, Tuning
from drivenav.agent.modes import approach, enrich, follow, scan, sweep
from drivenav.agent.planner import LocalPlanner
from drivenav.agent.relabel import carry_over
from drivenav.agent.state import EpisodeState, ValueSearch
from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import ScanStarted, ViewCaptured
from drivenav.directions import DirectionPipeline
from drivenav.inspection import RepresentativeViews, full_scan_turns
from drivenav.mapping.config import MappingConfig, MapTuning
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.value_map import ValueMap
from drivenav.paper import DriveNavConfig
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.protocols import Grounder, ImageTextScorer, ModelCall, Reasoner
from drivenav.types import SEMANTIC, Action, GroundTruth, Observation, SimConfig


class DriveNavAgent(Agent):
    """DRIVE-Nav (``drive-nav``) and, through :class:`AgentConfig`, its baselines."""

    def __init__(
        self,
        sim: SimConfig,
        config: AgentConfig | None = None,
        paper: DriveNavConfig | None = None,
        mapping: MapTuning | None = None,
        name: str = "drive-nav",
        reasoner_factory: Callable[[], Reasoner] = GeometricReasoner,
        grounder_factory: Callable[[], Grounder] = GroundTruthGrounder,
        requires: frozenset[str] = frozenset({SEMANTIC}),
        scorer_factory: Callable[[], ImageTextScorer] | None = None,
    ) -> None:
        super().__init__(sim)
        self.requires = requires  # what the models read of the world's ground truth (the default grounder: labels)
        self.name = name
        self.config = config or AgentConfig()
        self.paper = paper or DriveNavConfig()
        self.mapping = mapping or MapTuning()
        self.tuning = Tuning(sim, self.config, self.paper)
        self.uses_value_map = self.config.value_map and not self.config.use_reasoner  # VLFM
        if self.uses_value_map and scorer_factory is None:
            raise ValueError(f"{name}: the value map (agent.value_map) needs an image-text scorer")
        self.modes = self._modes()
        self._reasoner_factory = reasoner_factory
        self._grounder_factory = grounder_factory
        self._scorer_factory = scorer_factory
        self._grounder: Grounder | None = None  # built at the first episode and kept: weights load once
        self._scorer: ImageTextScorer | None = None  # likewise
        self.state: EpisodeState | None = None  # the running episode's state (none between episodes)

    def _modes(self) -> Modes:
        """The mode handlers: DRIVE-Nav's direction following, VLFM's value-map frontier choice (with its own end
        of the start scan) or the greedy nearest frontier."""
        if self.config.use_reasoner:
            start, following = scan.act, follow.act
        elif self.uses_value_map:
            start, following = vlfm.scan, vlfm.act
        else:
            start, following = scan.act, greedy.act
        return Modes(scan=start, sweep=sweep.act, follow=following, enrich=enrich.act, approach=approach.act)

    # ----------------------------------------------------------------- episode set-up

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        super().reset(goal_text, seed, truth)
        self.state = self._begin(goal_text, seed, truth)
        self.trace.add(ScanStarted(0, self.state.scan_turns))

    def _begin(self, goal_text: str, seed: int, truth: GroundTruth | None) -> EpisodeState:
        """A new episode: empty maps and views, a fresh planner, the models begun on the goal, a start scan.

        The grounder and the scorer (SAM3, OWLv2, BLIP-2: gigabytes of weights) are built at the first episode
        and begun anew at each; the reasoner (a client or a stand-in) is built per episode."""
        mapper = OccupancyMapper(MappingConfig.from_sim(self.sim, self.mapping))
        pipeline = DirectionPipeline(self.paper)
        views = RepresentativeViews(self.paper.inspection.view_tolerance)
        planner = LocalPlanner.from_config(self.sim, self.config.planner)
        reasoner = self._reasoner_factory()
        reasoner.begin_episode(goal_text, truth)
        if self._grounder is None:
            self._grounder = self._grounder_factory()
        grounder = self._grounder
        grounder.begin_episode(truth, seed)
        search = self._target_search(goal_text, grounder, reasoner)
        turns = full_scan_turns(self.tuning.turn)
        values = self._value_search(mapper, truth)
        return EpisodeState(mapper, pipeline, views, planner, reasoner, search, scan_turns=turns, values=values)

    def _value_search(self, mapper: OccupancyMapper, truth: GroundTruth | None) -> ValueSearch | None:
        """VLFM's scorer, begun on the episode, and an empty value map on the mapper's grid (None unless VLFM)."""
        if not self.uses_value_map or self._scorer_factory is None:
            return None
        if self._scorer is None:
            self._scorer = self._scorer_factory()
        scorer = self._scorer
        scorer.begin_episode(truth)
        return ValueSearch(scorer, ValueMap(mapper.grid, mapper.config.max_depth, self.config.vlfm))

    def _target_search(self, goal_text: str, grounder: Grounder, reasoner: Reasoner) -> TargetSearch:
        """Grounding, prompt enrichment and cross-frame verification as switched on, with the paper's rounds,
        frames and frame spacing (Sec. IV-B, IV-C)."""
        semantics = self.paper.semantics
        config = SearchConfig(
            self.config.enrich,
            self.config.verify,
            semantics.enrich_rounds,
            semantics.verify_frames,
            semantics.verify_spacing_steps,
        )
        search = TargetSearch(self.sim, config, grounder, reasoner)
        search.begin(goal_text)
        return search

    def end_episode(self) -> None:
        """Drop the episode: its maps, directions pipeline and views (tens of MB on a large floor plan) go before
        the next scene loads, not after (worker memory). Safe before any :meth:`reset` (a world that failed to
        reset the worker's first episode)."""
        super().end_episode()
        self.state = None

    def loop(self) -> Loop:
        """What the mode handlers work with this step: this agent, its tuning, the running episode, the modes."""
        if self.state is None:
            raise RuntimeError(f"{self.name}: no episode is running (reset the agent first)")
        return Loop(self, self.tuning, self.state, self.modes)

    # ----------------------------------------------------------------- what the episode cost and did

    def _calls(self) -> list[ModelCall]:
        """This episode's model calls: the reasoner's and, for VLFM, the scorer's (kind ``score``)."""
        if self.state is None:
            return []
        values = self.state.values
        return [*self.state.reasoner.calls, *(values.scorer.calls if values is not None else [])]

    @property
    def model_calls(self) -> int:
        return len(self._calls())

    def episode_stats(self) -> ModelStats:
        if self.state is None:
            return super().episode_stats()
        calls, search = self._calls(), self.state.search
        kinds = sorted({c.kind for c in calls})
        return ModelStats(
            vlm_calls_by_kind={k: sum(c.kind == k for c in calls) for k in kinds},
            vlm_latency_ms={k: round(sum(c.latency_ms for c in calls if c.kind == k), 2) for k in kinds},
            vlm_fallbacks=sum(c.outcome == "fallback" for c in calls),
            enrich_rounds=search.enrich_rounds,
            verifications={k: search.verifications.get(k, 0) for k in ("accepted", "rejected", "uncertain")},
            phrase=search.phrase,
        )

    def decision_stats(self) -> DecisionStats:
        if self.state is None:
            return super().decision_stats()
        return self.state.counts.freeze(*self.state.search.outcome())

    # ----------------------------------------------------------------- one step

    def decide(self, observation: Observation) -> Action:
        """Perceive (maps, directions, views, grounding), then continue the current mode; time each part."""
        loop = self.loop()
        state = loop.state
        timings: dict[str, float] = {}
        start = time.perf_counter()
        ctx = self._map(state, observation, timings)
        if state.values is not None:
            self._update_values(state.values, state.mapper, observation, timings)
        mark = time.perf_counter()
        carry_over(loop, ctx)
        self._record_views(state, observation, ctx)
        timings["inspection"] = _ms_since(mark)
        mark = time.perf_counter()
        state.search.observe(observation, self.trace)
        approach.track_target(loop)
        timings["grounding"] = _ms_since(mark)
        mark = time.perf_counter()
        action = loop.policy(observation, ctx)
        state.counts.count_step(action, state.activity(action))
        timings["policy"] = _ms_since(mark)
        timings["total"] = _ms_since(start)
        self.step_timings.append(timings)
        return action

    def _map(self, state: EpisodeState, observation: Observation, timings: dict[str, float]) -> StepContext:
        """Update the maps with the frame (and a robot's LiDAR, Sec. V-E) and solve for this step's directions."""
        start = time.perf_counter()
        mapper = state.mapper
        mapper.update(observation.depth, observation.intrinsics, observation.pose)
        if observation.occupancy is not None and mapper.config.fuse_lidar:
            mapper.fuse_occupancy(observation.occupancy)
        snapshot, frontiers = mapper.snapshot(), mapper.frontiers()
        timings["mapping"] = _ms_since(start)
        ctx = perceive(state.pipeline, observation.pose, snapshot, frontiers, state.goal)
        timings.update({f"directions.{k}": v for k, v in ctx.result.timings_ms.items()})
        return ctx

    def _update_values(
        self, values: ValueSearch, mapper: OccupancyMapper, observation: Observation, timings: dict[str, float]
    ) -> None:
        """VLFM: score the frame against the goal, then spread the score over the value map (on the mapper's grid,
        which may have grown this step); the scorer and the map update are timed apart."""
        start = time.perf_counter()
        score = values.scorer.score(self.goal_text, observation)
        timings["scorer"] = _ms_since(start)
        mark = time.perf_counter()
        values.value_map.follow(mapper.grid)
        values.value_map.update(score, observation.pose, observation.depth, observation.intrinsics)
        timings["value_map"] = _ms_since(mark)

    def _record_views(self, state: EpisodeState, observation: Observation, ctx: StepContext) -> None:
        """Keep the views of live and recently retired directions, and record a view of every direction the camera
        now faces better than before (Sec. IV-A c; not for the greedy baseline, which has no reasoner to show)."""
        views = state.views
        views.retain([*ctx.directions, *state.gone])
        if not self.config.use_reasoner:
            return
        for label, updated in views.observe(ctx.result.directions, observation, self.step):
            view = views.get(label)
            if view is not None:
                self.trace.add(ViewCaptured(self.step, label, view.pose.yaw, view.error, updated))


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
