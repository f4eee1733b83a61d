"""The agent body every exploration method shares (paper Sec. IV overview), and the agent it makes with an explorer.

Each step: depth + pose update the maps; one weighted-FMM solve of the directions pipeline turns the frontiers into
tracked directions and gives every frontier's path and the path to the current goal (Sec. IV-A a-b); the explorer
reads what it needs of the frame (:meth:`~drivenav.agent.explorer.Explorer.observe`: DRIVE-Nav's representative
views, VLFM's value map); the target search grounds the target (Sec. IV-B, IV-C). Then the body's approach drives
to a target candidate, verifying it on the way, and STOPs (:mod:`~drivenav.agent.approach`); otherwise the explorer
decides where to explore next (:meth:`~drivenav.agent.explorer.Explorer.act`). Collision recovery is the local
planner's; segments (the revisit metric) are marked by both.

What the body does is switched by :class:`~drivenav.agent.config.AgentConfig` (``enrich``, ``verify``, Table VI;
``fusion.enabled``: ApexNav's target-centric fusion decides which detections are the target,
:mod:`~drivenav.agent.fused_search`; ``stop_in_view``); the method's exploration by its explorer (``explorer.name``,
:mod:`drivenav.agent.explorers`). The reasoner's hints on the goal's category (ApexNav's category question) are
asked where fusion or the explorer reads them, once per category and agent (one worker's run): later episodes of
the category record a ``cached`` call instead. An episode's state
is one :class:`~drivenav.agent.state.BodyState` and one explorer, made by :meth:`ExplorerAgent.reset` and dropped
by :meth:`ExplorerAgent.end_episode`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivenav.agent import approach
from drivenav.agent.base import Agent, BodyCounters, CounterValue, ExplorerCounters, ModelCounters
from drivenav.agent.config import AgentConfig, ExplorerEntry
from drivenav.agent.context import StepContext, perceive
from drivenav.agent.explorer import Explorer, ExplorerContractError, ExplorerSetup, counter_values, sum_counters
from drivenav.agent.explorers import DEFAULT_EXPLORER, explorer_entry
from drivenav.agent.floors import NO_FRONTIER, STAIRS, Floor, Floors
from drivenav.agent.fused_search import FusedTargetSearch
from drivenav.agent.handles import StepHandles, Tuning
from drivenav.agent.planner import LocalPlanner
from drivenav.agent.state import BodyState
from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import Event, event_name, event_problem, is_builtin
from drivenav.directions import DirectionPipeline
from drivenav.errors import InputError
from drivenav.mapping.config import MappingConfig, MapTuning
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.paper import DriveNavConfig
from drivenav.plugins import load_object
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.protocols import (
    HINTS_KIND,
    CategoryHints,
    Grounder,
    ImageTextScorer,
    ModelCall,
    Reasoner,
)
from drivenav.types import SEMANTIC, Action, GroundTruth, Observation, SimConfig


def explorer_class(entry: ExplorerEntry) -> type[Explorer]:
    """The :class:`~drivenav.agent.explorer.Explorer` an entry names, imported now; one that cannot be imported or
    is no explorer is one :class:`~drivenav.errors.InputError` line naming the entry."""
    expected = f"the Explorer class {entry.explorer!r} of explorer {entry.name}"
    try:
        found = load_object(entry.explorer)
    except InputError:
        raise  # the explorer's own line (a missing extra)
    except Exception as error:
        raise InputError(f"explorer {entry.name}", "explorer", expected, f"{type(error).__name__}: {error}") from None
    if not (isinstance(found, type) and issubclass(found, Explorer)):
        raise InputError(f"explorer {entry.name}", "explorer", expected, found)
    return found


class ExplorerAgent(Agent):
    """The body with an explorer: DRIVE-Nav (``drive-nav``), its baselines, VLFM and any registered method."""

    def __init__(
        self,
        sim: SimConfig,
        config: AgentConfig | None = None,
        paper: DriveNavConfig | None = None,
        mapping: MapTuning | None = None,
        name: str = "drive-nav",
        explorer: ExplorerEntry | None = None,
        explorer_config: object | None = None,
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
        self.explorer_entry = explorer or explorer_entry(DEFAULT_EXPLORER)
        self.explorer_config = explorer_config if explorer_config is not None else self.explorer_entry.config()
        self.explorer_type = explorer_class(self.explorer_entry)
        self.uses_scorer = self.explorer_type.needs_scorer(self.explorer_config)
        if self.uses_scorer and scorer_factory is None:
            raise ValueError(f"{name}: the {self.explorer_entry.name} explorer needs an image-text scorer")
        self._reasoner_factory = reasoner_factory
        self._grounder_factory = grounder_factory
        self._scorer_factory = scorer_factory
        self._grounder: Grounder | None = None  # built at the first episode and kept: weights load once
        self._scorer: ImageTextScorer | None = None  # likewise
        self._hints: dict[str, CategoryHints] = {}  # the reasoner's hints by goal text, asked once per agent
        self.state: BodyState | None = None  # the running episode's state (none between episodes): its floor's
        self.explorer: Explorer | None = None  # the running episode's explorer: its floor's
        self.floors: Floors | None = None  # the episode's floors, with agent.floors.enabled
        self._truth: GroundTruth | None = None
        self._ctx: StepContext | None = None  # this step's perception (a floor change sets off from it)
        self._observation: Observation | None = None
        self._events_checked = 0  # the trace's events checked so far this episode (:meth:`_check_explorer`)

    # ----------------------------------------------------------------- episode set-up

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        super().reset(goal_text, seed, truth)
        self._truth = truth
        self._events_checked = 0
        self.state = self._begin(goal_text, seed, truth)
        self.explorer = self.explorer_type(self._explorer_setup(goal_text, truth, self.state.mapper))
        self.explorer.begin(self.handles())
        floors = self.config.floors
        first = Floor(0.0, self.state, self.explorer)
        self.floors = (
            Floors(floors, first, self._new_floor, self._switch_floor, self.sim.max_steps) if floors.enabled else None
        )

    def _begin(self, goal_text: str, seed: int, truth: GroundTruth | None) -> BodyState:
        """A new episode: empty maps, a fresh planner, the models begun on the goal.

        The grounder (SAM3, OWLv2: gigabytes of weights) is built at the first episode and begun anew at each; the
        reasoner (a client or a stand-in) is built per episode."""
        mapper = self._mapper()
        pipeline = DirectionPipeline(self.paper)
        planner = LocalPlanner.from_config(self.sim, self.config.planner)
        reasoner = self._reasoner_factory()
        reasoner.begin_episode(goal_text, truth)
        hints = self._category_hints(goal_text, reasoner)
        grounder = self._kept_grounder()
        grounder.begin_episode(truth, seed)
        search = self._target_search(goal_text, grounder, reasoner, hints)
        return BodyState(mapper, pipeline, planner, reasoner, search, hints=hints)

    def _mapper(self) -> OccupancyMapper:
        """A floor's empty maps; with floors on they read stairs from depth too."""
        floors = self.config.floors
        return OccupancyMapper(
            MappingConfig.from_sim(self.sim, self.mapping), floors.stairs if floors.enabled else None
        )

    def _new_floor(self) -> tuple[BodyState, Explorer]:
        """A floor first reached: its own empty maps, directions pipeline, planner, target search and explorer; the
        episode's reasoner, grounder, counters and hints (:mod:`drivenav.agent.floors`)."""
        assert self.state is not None and self._grounder is not None
        episode = self.state
        search = self._target_search(self.goal_text, self._grounder, episode.reasoner, episode.hints)
        pipeline, planner = DirectionPipeline(self.paper), LocalPlanner.from_config(self.sim, self.config.planner)
        state = BodyState(self._mapper(), pipeline, planner, episode.reasoner, search, counts=episode.counts)
        state.hints = episode.hints
        explorer = self.explorer_type(self._explorer_setup(self.goal_text, self._truth, state.mapper))
        return state, explorer

    def _switch_floor(self, floor: Floor) -> None:
        """The agent arrived on ``floor``: its state and explorer take over (a floor first reached begins its
        exploration, DRIVE-Nav's start scan)."""
        self.state, self.explorer = floor.state, floor.explorer
        if not floor.begun:
            floor.begun = True
            floor.explorer.begin(self.handles())

    def _category_hints(self, goal_text: str, reasoner: Reasoner) -> CategoryHints | None:
        """The reasoner's hints on the goal's category where fusion or the explorer reads them (None otherwise):
        asked at the first episode of the category, then answered from the agent's cache (a ``cached`` call)."""
        if not (self.config.fusion.enabled or self.explorer_type.uses_hints):
            return None
        key = " ".join(goal_text.lower().split())
        if key in self._hints:
            reasoner.calls.append(ModelCall(HINTS_KIND, 0.0, "cached"))
        else:
            self._hints[key] = reasoner.category_hints(goal_text)
        return self._hints[key]

    def _explorer_setup(self, goal_text: str, truth: GroundTruth | None, mapper: OccupancyMapper) -> ExplorerSetup:
        """What the explorer is made from; the image-text scorer (BLIP-2: gigabytes) is built at the first episode
        of an explorer that uses one, and kept."""
        scorer = self._kept_scorer()
        hints = self.state.hints if self.state is not None and self.explorer_type.uses_hints else None
        return ExplorerSetup(self.explorer_config, self.tuning, goal_text, truth, mapper, scorer, hints)

    def start_models(self) -> None:
        """Build the models as the first episode would, before it: the grounder and the image-text scorer are kept
        for the episodes, a reasoner (one per episode) is built once to see that it can be."""
        self._reasoner_factory()
        self._kept_grounder()
        self._kept_scorer()

    def _kept_grounder(self) -> Grounder:
        """The grounder, built at its first use and kept (SAM3, OWLv2: gigabytes of weights load once)."""
        if self._grounder is None:
            self._grounder = self._grounder_factory()
        return self._grounder

    def _kept_scorer(self) -> ImageTextScorer | None:
        """The image-text scorer of an explorer that uses one (BLIP-2: gigabytes), built at its first use and kept;
        None for the others."""
        if self.uses_scorer and self._scorer is None and self._scorer_factory is not None:
            self._scorer = self._scorer_factory()
        return self._scorer if self.uses_scorer else None

    def _target_search(
        self, goal_text: str, grounder: Grounder, reasoner: Reasoner, hints: CategoryHints | None
    ) -> TargetSearch:
        """Grounding, prompt enrichment and cross-frame verification as switched on, with the paper's rounds,
        frames and frame spacing (Sec. IV-B, IV-C); with fusion on, detections fused per object instead."""
        semantics = self.paper.semantics
        config = SearchConfig(
            self.config.enrich,
            self.config.verify,
            semantics.enrich_rounds,
            semantics.verify_frames,
            semantics.verify_spacing_steps,
        )
        fusion = self.config.fusion
        if fusion.enabled:
            search: TargetSearch = FusedTargetSearch(
                self.sim, config, grounder, reasoner, fusion, hints or CategoryHints.unknown()
            )
        else:
            search = TargetSearch(self.sim, config, grounder, reasoner)
        search.begin(goal_text)
        return search

    def end_episode(self) -> None:
        """Drop the episode: its maps, directions pipeline and the explorer's memory (tens of MB on a large floor
        plan) go before the next scene loads, not after (worker memory). Safe before any :meth:`reset` (a world
        that failed to reset the worker's first episode)."""
        super().end_episode()
        self.state = None
        self.explorer = None
        self.floors = None
        self._ctx = None
        self._observation = None

    def handles(self) -> StepHandles:
        """What the approach and the explorer work with this step: this agent, its tuning, the episode."""
        if self.state is None or self.explorer is None:
            raise RuntimeError(f"{self.name}: no episode is running (reset the agent first)")
        return StepHandles(self, self.tuning, self.state, self.explorer, approach.act)

    # ----------------------------------------------------------------- what the episode cost and did

    def _calls(self) -> list[ModelCall]:
        """This episode's model calls: the reasoner's and the explorer's (VLFM's scorer: kind ``score``)."""
        if self.state is None or self.explorer is None:
            return []
        return [*self.state.reasoner.calls, *(call for e in self._explorers() for call in e.model_calls())]

    def _explorers(self) -> list[Explorer]:
        """Every floor's explorer this episode (the one explorer without floors)."""
        if self.floors is not None:
            return self.floors.explorers()
        return [self.explorer] if self.explorer is not None else []

    def _searches(self) -> list[TargetSearch]:
        """Every floor's target search this episode."""
        if self.floors is not None:
            return [state.search for state in self.floors.states()]
        return [self.state.search] if self.state is not None else []

    @property
    def model_calls(self) -> int:
        return len(self._calls())

    def episode_stats(self) -> ModelCounters:
        if self.state is None:
            return super().episode_stats()
        calls, search = self._calls(), self.state.search
        kinds = sorted({c.kind for c in calls})
        return ModelCounters(
            vlm_calls_by_kind={k: sum(c.kind == k for c in calls) for k in kinds},
            vlm_latency_ms={k: round(sum(c.latency_ms for c in calls if c.kind == k), 2) for k in kinds},
            vlm_fallbacks=sum(c.outcome == "fallback" for c in calls),
            enrich_rounds=search.enrich_rounds,
            verifications={k: search.verifications.get(k, 0) for k in ("accepted", "rejected", "uncertain")},
            phrase=search.phrase,
        )

    def body_counters(self) -> BodyCounters:
        if self.state is None:
            return super().body_counters()
        outcomes = [search.outcome() for search in self._searches()]
        created, accepted, aside = (sum(o[k] for o in outcomes) for k in range(3))
        return self.state.counts.freeze(created, accepted, aside)

    def explorer_counters(self) -> ExplorerCounters | None:
        """The explorer's name and counters; counters that break the contract (the step that met them ended the
        episode in an error, :meth:`_check_explorer`) are left out, so that the record is always readable."""
        if self.explorer is None:
            return ExplorerCounters(self.explorer_entry.name)
        try:
            counters = self._counters()
        except ExplorerContractError:
            return ExplorerCounters(self.explorer_entry.name)
        return ExplorerCounters(self.explorer_entry.name, counters)

    def _counters(self) -> dict[str, CounterValue]:
        """Every floor's explorer's counters, checked and summed; a violation is an :class:`ExplorerContractError`."""
        try:
            return sum_counters([counter_values(e.counters()) for e in self._explorers()])
        except (ValueError, TypeError) as error:
            raise ExplorerContractError(self.explorer_entry.name, str(error)) from None

    def _check_explorer(self, action: object) -> None:
        """What the explorer handed the body this step, checked where it receives it: the action is an
        :class:`~drivenav.types.Action`, the counters fit the record, the trace events of plug-in kinds added since
        the last check can be saved (one that cannot is dropped from the trace, so that the trace is written). A
        violation is an :class:`ExplorerContractError`: the episode ends in an error naming the explorer."""
        name = self.explorer_entry.name
        if not isinstance(action, Action):
            raise ExplorerContractError(name, f"act() returned {action!r}, not an Action member")
        self._counters()
        events = self.trace.events
        new = range(self._events_checked, len(events))
        bad = [
            (index, problem)
            for index in new
            if not is_builtin(events[index]) and (problem := event_problem(events[index]))
        ]
        if bad:
            first = events[bad[0][0]]
            kind = event_name(first) if isinstance(first, Event) else type(first).__name__
            for index, _ in reversed(bad):
                del events[index]
            raise ExplorerContractError(name, f"trace event {kind!r} at step {self.step}: {bad[0][1]}")
        self._events_checked = len(events)

    # ----------------------------------------------------------------- one step

    def decide(self, observation: Observation) -> Action:
        """Perceive (maps, directions, the explorer's reading, grounding), then approach or explore; time each
        part. The grounder is told the frame's phrases first, so that a served one grounds while the frame is
        mapped. With floors on, a step on stairs only climbs (the maps are left as they are), and a step toward
        stairs the floor rule set off for is the floors' (:mod:`drivenav.agent.floors`)."""
        timings: dict[str, float] = {}
        start = time.perf_counter()
        floors = self.floors
        if floors is not None and floors.on_stairs(observation):
            climbed = floors.climb(self.handles(), observation)
            if climbed is not None:
                return self._counted(climbed, STAIRS, timings, start)
        handles = self.handles()
        state = handles.state
        mark = time.perf_counter()
        state.search.prefetch(observation)  # a served grounder grounds the frame while it is mapped
        told = _ms_since(mark)
        ctx = self._map(state, observation, timings)
        self._ctx, self._observation = ctx, observation
        handles.explorer.observe(handles, observation, ctx, timings)
        mark = time.perf_counter()
        state.search.observe(observation, self.trace, ctx.snapshot, handles.explorer.frame_score(), timings)
        approach.track_target(handles)
        timings["grounding"] = told + _ms_since(mark) - timings.get("fusion", 0.0)
        mark = time.perf_counter()
        if floors is not None and floors.trip is None and not state.approaching:
            floors.look(observation)
            floors.ask(handles, ctx)
        if floors is not None and floors.trip is not None and not state.approaching:
            toward = floors.heading_for_stairs(handles, observation, ctx)
            if toward is not None:
                timings["policy"] = _ms_since(mark)
                return self._counted(toward, STAIRS, timings, start)
        action = handles.policy(observation, ctx)
        handles = self.handles()  # the floor rule may have set off for stairs within the explorer's step
        activity = STAIRS if floors is not None and floors.trip is not None else None
        timings["policy"] = _ms_since(mark)
        return self._counted(action, activity or self._activity(handles, action), timings, start)

    def _activity(self, handles: StepHandles, action: Action) -> str:
        return handles.state.activity(action) or handles.explorer.activity(handles.state.planner.escaping)

    def _counted(self, action: Action, activity: str, timings: dict[str, float], start: float) -> Action:
        """Check what the explorer handed the body, count the step under ``activity`` and keep its timings."""
        assert self.state is not None
        self._check_explorer(action)
        self.state.counts.count_step(action, activity)
        timings["total"] = _ms_since(start)
        self.step_timings.append(timings)
        return action

    def stop(self, reason: str) -> Action:
        """STOP, unless the floor rule finds a way to a floor with something left to explore (floors on): then
        the step sets off for it."""
        floors, ctx, observation = self.floors, self._ctx, self._observation
        if reason == NO_FRONTIER and floors is not None and ctx is not None and observation is not None:
            handles = self.handles()
            if floors.trip is None and floors.leave(handles, ctx):
                toward = floors.heading_for_stairs(handles, observation, ctx)
                if toward is not None:
                    return toward
        return super().stop(reason)

    def _map(self, state: BodyState, observation: Observation, timings: dict[str, float]) -> StepContext:
        """Update the maps with the frame (and a robot's LiDAR, Sec. V-E) and solve for this step's directions."""
        start = time.perf_counter()
        mapper = state.mapper
        rise = observation.pose.z - self.floors.floor.level if self.floors is not None else 0.0
        mapper.update(observation.depth, observation.intrinsics, observation.pose, rise)
        if observation.occupancy is not None and mapper.config.fuse_lidar:
            mapper.fuse_occupancy(observation.occupancy)
        snapshot, frontiers = mapper.snapshot(), mapper.frontiers()
        timings["mapping"] = _ms_since(start)
        ctx = perceive(state.pipeline, observation.pose, snapshot, frontiers, state.goal)
        timings.update({f"directions.{k}": v for k, v in ctx.result.timings_ms.items()})
        return ctx


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
