"""drive-nav-plus, DRIVE-Nav beyond the paper (docs/agent.md "Beyond the paper"): each rule behind its switch (settled
directions, void events and forced choices, a turn back to the near remainder), hand-built cases of each, an
end-to-end episode, and the report pairing it with drive-nav."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agent_scenes import episode_for, t_junction
from drivenav.agent.base import ExplorerCounters
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav import decision, sweep
from drivenav.agent.explorers.drive_nav.decision import candidates
from drivenav.agent.explorers.drive_nav.explorer import DirectionsExplorer
from drivenav.agent.explorers.drive_nav.memory import Directions, Phase, settled
from drivenav.agent.explorers.drive_nav.relabel import carry_over, relabel
from drivenav.agent.trace import DirectionSelected, InspectionVoid, of_type
from drivenav.agents import make_agent
from drivenav.analysis.beyond import PairedEntry, beyond_table_ii, paired_entries
from drivenav.analysis.paper_tables import TABLE_II_METHODS
from drivenav.directions.types import Direction, DirectionResult, FrontierPath
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.runner import run_episode
from drivenav.semantics.protocols import Candidate, View
from drivenav.settings import load_settings
from drivenav.types import Action, CameraIntrinsics, GroundTruth, Observation, Pose, SimConfig

METHODS = ("drive-nav", "drive-nav-plus")

# ----------------------------------------------------------------------------------------------- helpers


def _path(frontier: int, target: tuple[float, float], time: float) -> FrontierPath:
    line = np.array([[0.0, 0.0], target])
    return FrontierPath(frontier, target, time, line, target, 0.0, target)


# ----------------------------------------------------------------------------------------------- the rules


def _direction(label: int, bearing_deg: float) -> Direction:
    point = np.array([[math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg))]]) * (2 + label)
    far = (float(point[0, 0]), float(point[0, 1]))
    return Direction(label, math.radians(bearing_deg), (label,), (math.radians(bearing_deg),), point, point, far)


def _agent(name: str, bearings_deg: dict[int, float]) -> tuple[ExplorerAgent, Directions, StepContext]:
    agent = make_agent(load_settings(name))
    assert isinstance(agent, ExplorerAgent) and isinstance(agent.explorer_type, type)
    agent.reset("chair", 0, GroundTruth({}, VOCABULARY))
    assert isinstance(agent.explorer, DirectionsExplorer)
    directions = tuple(_direction(label, b) for label, b in sorted(bearings_deg.items()))
    ctx = StepContext(Pose(0.0, 0.0, 0.0), None, [], DirectionResult(directions, {}, ()), None)  # type: ignore[arg-type]
    return agent, agent.explorer.memory, ctx


def _observation() -> Observation:
    intrinsics = CameraIntrinsics.from_hfov(8, 6, 79.0)
    depth = np.full((6, 8), 2.0, np.float32)
    return Observation(np.zeros((6, 8, 3), np.uint8), depth, None, Pose(0.0, 0.0, 0.0), intrinsics, 0, False)


def _view(label: int, step: int) -> View:
    return View(label, np.zeros((2, 2, 3), np.uint8), None, Pose(0.0, 0.0, 0.0), 0.0, 0.0, step)


def _after_a_sweep(name: str, monkeypatch: pytest.MonkeyPatch) -> tuple[ExplorerAgent, Directions, list[str], Action]:
    """The step a sweep ends at: the followed direction 0 is still tracked, the event's direction 9 is gone."""
    agent, memory, ctx = _agent(name, {0: 10.0, 1: 90.0})
    memory.phase, memory.pending_yaws, memory.selected, memory.event_labels = Phase.SWEEP, [], 0, (9,)
    decided: list[str] = []
    monkeypatch.setattr(sweep, "decide", lambda d, handles, obs, ctx, reason: decided.append(reason) or Action.STOP)
    handles = agent.handles()
    monkeypatch.setattr(handles, "policy", lambda obs, ctx: Action.MOVE_FORWARD)
    return agent, memory, decided, sweep.act(memory, handles, _observation(), ctx)


def test_a_void_inspection_event_goes_back_to_following_without_a_decision(monkeypatch: pytest.MonkeyPatch) -> None:
    agent, memory, decided, action = _after_a_sweep("drive-nav-plus", monkeypatch)
    assert (action, decided, memory.phase, memory.counts.void_events) == (Action.MOVE_FORWARD, [], Phase.FOLLOW, 1)
    assert [e.labels for e in of_type(agent.trace.events, InspectionVoid)] == [(9,)]
    assert not of_type(agent.trace.events, DirectionSelected)


def test_the_paper_asks_the_reasoner_after_every_sweep(monkeypatch: pytest.MonkeyPatch) -> None:
    agent, memory, decided, action = _after_a_sweep("drive-nav", monkeypatch)
    assert (action, decided, memory.counts.void_events) == (Action.STOP, ["inspection"], 0)
    assert not of_type(agent.trace.events, InspectionVoid)


def test_an_event_is_void_only_when_its_directions_are_gone_the_followed_one_is_not_and_no_view_is_new() -> None:
    agent, memory, ctx = _agent("drive-nav-plus", {0: 10.0, 1: 90.0, 2: 200.0})
    memory.selected = 0
    for labels, selected, void in (((9,), 0, True), ((1, 9), 0, False), ((9,), 7, False)):
        memory.event_labels, memory.selected = labels, selected
        assert sweep.void(memory, agent.handles(), ctx) is void
    memory.event_labels, memory.selected = (9,), 0
    memory.views._views = {1: _view(1, 5), 2: _view(2, 6)}  # direction 2 lies behind the event's heading
    assert sweep.void(memory, agent.handles(), ctx) is False  # the sweep captured a view of direction 1: judge it
    memory.judged = {5}
    assert sweep.void(memory, agent.handles(), ctx) is True  # seen before; direction 2's view is not offered


def test_a_single_direction_whose_view_the_reasoner_judged_is_followed_without_asking() -> None:
    _, memory, _ = _agent("drive-nav-plus", {0: 10.0})
    seen, unseen, blind = (Candidate(0, 0.0, 0.0, 1.0, 9, view) for view in (_view(0, 3), _view(0, 7), None))
    memory.judged = {3}
    assert decision.forced(memory, [seen]) and decision.forced(memory, [blind])
    assert not decision.forced(memory, [unseen]) and not decision.forced(memory, [seen, blind])
    _, paper, _ = _agent("drive-nav", {0: 10.0})
    paper.judged = {3}
    assert not decision.forced(paper, [seen])


def _tracked(agent: ExplorerAgent, memory: Directions, ctx: StepContext, step: int) -> bool:
    """Step ``step`` of following direction 0 with direction 1 in sight: whether an inspection event starts."""
    agent.step = step
    carry_over(memory, agent.handles(), ctx)
    return sweep.inspection_event(memory, agent.handles(), ctx)


@pytest.mark.parametrize(("name", "first_event"), [("drive-nav-plus", 3), ("drive-nav", 0)])
def test_a_new_direction_starts_an_inspection_event_once_settled(name: str, first_event: int) -> None:
    agent, memory, ctx = _agent(name, {0: 10.0, 1: 60.0})
    memory.phase, memory.selected, memory.inspected, memory.born = Phase.FOLLOW, 0, {0}, {0: 0}
    memory.views._views = {0: _view(0, 0)}
    starts = [_tracked(agent, memory, ctx, step) for step in range(10, 10 + first_event + 1)]
    assert starts == [False] * first_event + [True] and memory.event_labels == (1,) and memory.born[1] == 10


def test_a_direction_seen_in_passing_while_it_settled_is_still_asked_about_without_turning() -> None:
    agent, memory, ctx = _agent("drive-nav-plus", {0: 10.0, 1: 60.0})
    memory.phase, memory.selected, memory.inspected, memory.born = Phase.FOLLOW, 0, {0}, {0: 0}
    memory.views._views = {0: _view(0, 0)}
    assert not _tracked(agent, memory, ctx, 10)
    memory.views._views[1] = _view(1, 11)  # the camera faced it on the way
    assert [_tracked(agent, memory, ctx, step) for step in (11, 12, 13)] == [False, False, True]
    assert memory.event_labels == (1,) and memory.pending_yaws == []  # a decision, no sweep
    _, judged, ctx = _agent("drive-nav-plus", {0: 10.0, 1: 60.0})
    judged.views._views, judged.judged, judged.born = {0: _view(0, 0), 1: _view(1, 11)}, {11}, {0: 0, 1: 0}
    judged.selected, judged.inspected = 0, {0}
    assert not sweep.inspection_event(judged, agent.handles(), ctx)  # the reasoner has seen that view


@pytest.mark.parametrize(("name", "score", "judged", "checked", "due"), [
    ("drive-nav-plus", 0.5, set(), set(), [1]),  # a new view as promising as a view of the goal: judged now
    ("drive-nav-plus", 0.49, set(), set(), []),
    ("drive-nav-plus", 0.9, {11}, set(), []),  # the reasoner has seen it
    ("drive-nav-plus", 0.9, set(), {1}, []),  # checked once already
    ("drive-nav-plus-no-check", 0.9, set(), set(), []),
    ("drive-nav", 0.9, set(), set(), []),
])  # fmt: skip
def test_a_promising_unjudged_forward_view_is_judged_at_once_once(
    name: str, score: float, judged: set[int], checked: set[int], due: list[int]
) -> None:
    agent, memory, ctx = _agent(name, {0: 10.0, 1: 60.0, 2: 170.0})
    memory.views._views = {0: _view(0, 0), 1: _view(1, 11), 2: _view(2, 12)}  # 2 lies behind: never
    memory.view_scores, memory.judged, memory.checked = {0: 0.0, 11: score, 12: 0.9}, {0} | judged, checked
    assert sweep.promising_views(memory, agent.handles(), ctx) == due


def test_only_a_method_with_the_target_check_loads_the_image_text_scorer() -> None:
    paper, plus = (make_agent(load_settings(name)) for name in METHODS)
    assert isinstance(paper, ExplorerAgent) and isinstance(plus, ExplorerAgent)
    assert (paper.uses_scorer, plus.uses_scorer) == (False, True)
    paper.reset("chair", 0, GroundTruth({}, VOCABULARY))
    assert isinstance(paper.explorer, DirectionsExplorer) and paper.explorer.scorer is None


def test_a_split_that_merges_back_before_it_settles_starts_no_event() -> None:
    agent, memory, with_split = _agent("drive-nav-plus", {0: 10.0, 1: 60.0})
    memory.phase, memory.selected, memory.inspected, memory.born = Phase.FOLLOW, 0, {0}, {0: 0}
    memory.views._views = {0: _view(0, 0)}
    alone = StepContext(with_split.pose, None, [], DirectionResult(with_split.result.directions[:1], {}, ()), None)  # type: ignore[arg-type]
    layouts = [with_split, with_split, alone, alone, alone, alone]  # direction 1 is tracked for two steps only
    assert not any(_tracked(agent, memory, ctx, step) for step, ctx in enumerate(layouts, start=10))
    assert 1 not in memory.inspected and memory.counts.inspection_events == 0


def test_a_merged_direction_is_tracked_since_its_earliest_parent() -> None:
    _, memory, _ = _agent("drive-nav-plus", {5: 10.0})
    memory.born = {3: 4, 4: 9}
    relabel(memory, 5, (3, 4), 0.0)
    assert memory.born[5] == 4
    assert settled(memory, 6, 5) is False and settled(memory, 7, 5) is True


def _two_piece_direction() -> tuple[Direction, StepContext]:
    """Direction 0 behind the robot: a frontier 1 m away and one 6 m away, its farthest point 7 m away."""
    direction = Direction(0, math.pi, (0, 1), (math.pi, math.pi), np.zeros((2, 2)), np.zeros((2, 2)), (-7.0, 0.0))
    paths = {0: _path(0, (-1.0, 0.0), 1.0), 1: _path(1, (-6.0, 0.0), 6.0)}
    ctx = StepContext(Pose(0.0, 0.0, 0.0), None, [], DirectionResult((direction,), paths, ()), None)  # type: ignore[arg-type]
    return direction, ctx


@pytest.mark.parametrize(("name", "turning_back", "goal"), [
    ("drive-nav-plus", True, (-1.0, 0.0)),  # nothing left ahead: the near remainder first
    ("drive-nav-plus", False, (-7.0, 0.0)),  # going on: the farthest frontier point, as the paper
    ("drive-nav", True, (-7.0, 0.0)),
])  # fmt: skip
def test_turning_back_follows_the_nearest_frontier_only_when_return_aware(
    name: str, turning_back: bool, goal: tuple[float, float]
) -> None:
    agent, memory, _ = _agent(name, {})
    direction, ctx = _two_piece_direction()
    memory.turning_back = turning_back
    decision.select(memory, agent.handles(), ctx, direction, "vanished", [0], False)
    assert memory.returning is (name == "drive-nav-plus" and turning_back)
    assert agent.state is not None and agent.state.goal == goal == decision.goal_point(memory, ctx, direction)
    [event] = of_type(agent.trace.events, DirectionSelected)
    assert event.goal == goal


def test_a_decision_with_nothing_ahead_is_turning_back() -> None:
    agent, memory, ctx = _agent("drive-nav-plus", {0: 170.0, 1: 30.0})
    memory.views._views = {}
    for bearings, behind in (({0: 170.0, 1: 30.0}, False), ({0: 170.0}, True)):
        directions = tuple(_direction(label, b) for label, b in sorted(bearings.items()))
        ctx = StepContext(ctx.pose, None, [], DirectionResult(directions, {}, ()), None)  # type: ignore[arg-type]
        candidates(memory, agent.handles(), ctx, "vanished")
        assert memory.turning_back is behind
    candidates(memory, agent.handles(), ctx, "scan")  # the start scan offers all around: no turning back
    assert memory.turning_back is False


# ----------------------------------------------------------------------------------------------- the report


def _record(method: str, episode: int, success: int, spl: float, decisions: int) -> EpisodeRecord:
    explorer = ExplorerCounters("directions", {"decisions": {"inspection": decisions}})
    return EpisodeRecord(
        str(episode), "s", "chair", method, 100, 0, "stop", "", success=success, spl=spl, geodesic_distance=12.0,
        explorer=explorer,
    )  # fmt: skip


def test_a_method_beyond_the_paper_is_paired_with_its_base() -> None:
    plus = [(1, 0.5, 4), (1, 0.4, 6), (0, 0.0, 8), (1, 0.9, 2)]
    base = [(1, 0.3, 9), (0, 0.0, 11), (1, 0.6, 13), (1, 0.9, 2)]
    runs = {
        "drive-nav-plus": {str(k): _record("drive-nav-plus", k, *v) for k, v in enumerate(plus)},
        "drive-nav": {str(k): _record("drive-nav", k, *v) for k, v in enumerate(base)},
    }
    [(name, entry)] = paired_entries(runs).items()
    assert (name, entry.base, entry.episodes, entry.sr_wins, entry.sr_losses) == (
        "drive-nav-plus",
        "drive-nav",
        4,
        1,
        1,
    )
    assert entry.spl_delta == pytest.approx((0.2 + 0.4 - 0.6 + 0.0) / 4)
    low, high = entry.spl_delta_ci95
    assert low <= entry.spl_delta <= high
    assert (entry.median_decisions, entry.base_median_decisions) == (5.0, 10.0)
    assert PairedEntry.from_json(entry.to_json()) == entry
    table = beyond_table_ii(runs, TABLE_II_METHODS)
    assert table is not None and set(table.methods) == {"drive-nav", "drive-nav-plus"} and table.common_episodes == 2
    assert beyond_table_ii({"drive-nav": runs["drive-nav"]}, TABLE_II_METHODS) is None
    rows = {**runs, "drive-nav-plus-no-void": runs["drive-nav-plus"]}  # an ablation row is paired, not in Table II
    assert set(paired_entries(rows)) == {"drive-nav-plus", "drive-nav-plus-no-void"}
    with_rows = beyond_table_ii(rows, TABLE_II_METHODS)
    assert with_rows is not None and set(with_rows.methods) == {"drive-nav", "drive-nav-plus"}


# ----------------------------------------------------------------------------------------------- end to end


@pytest.mark.parametrize("target_on_left", [True, False])
def test_at_a_t_junction_drive_nav_plus_finds_the_target_asking_fewer_questions(target_on_left: bool) -> None:
    scene = t_junction(target_on_left)
    env = EmbeddedEnv(lambda _: scene, SimConfig())
    episode = episode_for(scene, (12.0, 2.5), math.pi / 2, "plant")
    records = [run_episode(env, make_agent(load_settings(name)), episode, 0, 300)[0] for name in METHODS]
    paper, plus = (record.explorer.counters for record in records if record.explorer is not None)
    assert [record.success for record in records] == [1, 1]
    asked = [sum(counters["decisions"].values()) for counters in (paper, plus)]  # type: ignore[union-attr]
    reasoner_calls = [r.vlm_calls - r.stats.vlm_calls_by_kind.get("score", 0) for r in records]  # not the scorer's
    assert asked[1] <= asked[0] and reasoner_calls[1] <= reasoner_calls[0]  # the target check may ask once more
