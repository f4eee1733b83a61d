"""drive-nav-plus, DRIVE-Nav beyond the paper (docs/agent.md "Beyond the paper"): each rule behind its switch, the
map evidence it reads (hand-computed), what the reasoners are told, and the report pairing it with drive-nav."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agent_scenes import episode_for, t_junction
from drivenav.agent.base import ExplorerStats
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions import decision, sweep
from drivenav.agent.explorers.directions.decision import candidates
from drivenav.agent.explorers.directions.explorer import DirectionsExplorer
from drivenav.agent.explorers.directions.memory import Directions, Phase
from drivenav.agent.explorers.directions.returns import return_time
from drivenav.agent.trace import DirectionSelected, InspectionVoid, of_type
from drivenav.agents import make_agent
from drivenav.analysis.beyond import PairedEntry, beyond_table_ii, paired_entries
from drivenav.analysis.paper_tables import TABLE_II_METHODS
from drivenav.directions.types import Direction, DirectionResult, FrontierPath
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.runner import run_episode
from drivenav.semantics.embedded import EmbeddedReasoner, EmbeddedReasonerConfig, return_factor
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.prompts import select_text
from drivenav.semantics.protocols import Candidate, View
from drivenav.semantics.replay import select_request
from drivenav.settings import load_settings
from drivenav.types import Action, CameraIntrinsics, GroundTruth, Observation, Pose, SimConfig

METHODS = ("drive-nav", "drive-nav-plus")

# ----------------------------------------------------------------------------------------------- the way back


def _path(frontier: int, target: tuple[float, float], time: float) -> FrontierPath:
    line = np.array([[0.0, 0.0], target])
    return FrontierPath(frontier, target, time, line, target, 0.0, target)


def test_the_way_back_from_a_direction_is_its_farthest_members_way_on_to_its_farthest_point() -> None:
    far = (3.0, 4.0)
    direction = Direction(0, 0.0, (0, 1, 2), (0.0, 0.0, 0.0), np.zeros((3, 2)), np.zeros((3, 2)), far)
    paths = {0: _path(0, (1.0, 0.0), 1.0), 1: _path(1, (3.0, 0.0), 3.0)}  # frontier 2 is unreachable
    ctx = StepContext(Pose(0.0, 0.0, 0.0), None, [], DirectionResult((direction,), paths, (2,)), None)  # type: ignore[arg-type]
    assert return_time(ctx, direction) == pytest.approx(3.0 + 4.0)
    lost = StepContext(Pose(0.0, 0.0, 0.0), None, [], DirectionResult((direction,), {}, ()), None)  # type: ignore[arg-type]
    assert return_time(lost, direction) == math.inf


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


def _after_a_sweep(name: str, monkeypatch: pytest.MonkeyPatch) -> tuple[ExplorerAgent, Directions, list[str], Action]:
    """The step a sweep ends at: the followed direction 0 is still tracked, the event's direction 9 is gone."""
    agent, memory, ctx = _agent(name, {0: 10.0, 1: 90.0})
    memory.phase, memory.pending_yaws, memory.selected, memory.event_labels = Phase.SWEEP, [], 0, (9,)
    decided: list[str] = []
    monkeypatch.setattr(sweep, "decide", lambda d, loop, obs, ctx, reason: decided.append(reason) or Action.STOP)
    loop = agent.loop()
    monkeypatch.setattr(loop, "policy", lambda obs, ctx: Action.MOVE_FORWARD)
    return agent, memory, decided, sweep.act(memory, loop, _observation(), ctx)


def test_a_void_inspection_event_goes_back_to_following_without_a_decision(monkeypatch: pytest.MonkeyPatch) -> None:
    agent, memory, decided, action = _after_a_sweep("drive-nav-plus", monkeypatch)
    assert (action, decided, memory.phase, memory.counts.void_events) == (Action.MOVE_FORWARD, [], Phase.FOLLOW, 1)
    assert [e.labels for e in of_type(agent.trace.events, InspectionVoid)] == [(9,)]
    assert not of_type(agent.trace.events, DirectionSelected)


def test_the_paper_asks_the_reasoner_after_every_sweep(monkeypatch: pytest.MonkeyPatch) -> None:
    agent, memory, decided, action = _after_a_sweep("drive-nav", monkeypatch)
    assert (action, decided, memory.counts.void_events) == (Action.STOP, ["inspection"], 0)
    assert not of_type(agent.trace.events, InspectionVoid)


def test_an_event_is_void_only_when_its_directions_are_gone_and_the_followed_one_is_not() -> None:
    _, memory, ctx = _agent("drive-nav-plus", {0: 10.0, 1: 90.0})
    memory.selected = 0
    for labels, selected, void in (((9,), 0, True), ((1, 9), 0, False), ((9,), 7, False)):
        memory.event_labels, memory.selected = labels, selected
        assert sweep.void(memory, ctx) is void


def _view(label: int, step: int) -> View:
    return View(label, np.zeros((2, 2, 3), np.uint8), None, Pose(0.0, 0.0, 0.0), 0.0, 0.0, step)


def test_a_single_direction_whose_view_the_reasoner_judged_is_followed_without_asking() -> None:
    _, memory, _ = _agent("drive-nav-plus", {0: 10.0})
    seen, unseen, blind = (Candidate(0, 0.0, 0.0, 1.0, 9, view) for view in (_view(0, 3), _view(0, 7), None))
    memory.judged = {3}
    assert decision.forced(memory, [seen]) and decision.forced(memory, [blind])
    assert not decision.forced(memory, [unseen]) and not decision.forced(memory, [seen, blind])
    _, paper, _ = _agent("drive-nav", {0: 10.0})
    paper.judged = {3}
    assert not decision.forced(paper, [seen])


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
    decision.select(memory, agent.loop(), ctx, direction, "vanished", [0], False)
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
        candidates(memory, agent.loop(), ctx, "vanished")
        assert memory.turning_back is behind
    candidates(memory, agent.loop(), ctx, "scan")  # the start scan offers all around: no turning back
    assert memory.turning_back is False


# ----------------------------------------------------------------------------------------------- reasoners


def _candidate(label: int, cells: int = 60, return_time: float | None = None) -> Candidate:
    return Candidate(label, 0.0, 0.0, 2.0, cells, None, return_time=return_time)


def test_the_way_back_discounts_a_candidate_by_hand() -> None:
    config = EmbeddedReasonerConfig()
    assert return_factor(_candidate(0), config) == 1.0  # the paper's candidate: nothing measured
    assert return_factor(_candidate(0, return_time=10.0), config) == pytest.approx(1 / (1 + 10.0 / 5.0))
    assert return_factor(_candidate(0, return_time=math.inf), config) == 0.0


def test_the_embedded_reasoner_finishes_the_nearer_branch_first_only_when_told() -> None:
    reasoner = EmbeddedReasoner(default_embedder())
    reasoner.begin_episode("sofa", GroundTruth({}, VOCABULARY))
    assert reasoner.select_direction("sofa", [_candidate(0, 80), _candidate(1, 60)]).label == 0
    told = [_candidate(0, 80, return_time=9.0), _candidate(1, 60, return_time=2.0)]
    assert reasoner.select_direction("sofa", told).label == 1


def test_a_vlm_is_told_the_way_back_and_nothing_new_without_it() -> None:
    plain = select_text("sofa", [_candidate(3)], 0)
    assert "far end" not in plain and "coming back" not in plain
    told = select_text("sofa", [_candidate(3, return_time=6.54)], 0)
    line = next(text for text in told.splitlines() if text.startswith("- direction 3"))
    assert line.endswith(
        "60 unexplored frontier cells, its far end 6.5 m away (the way back if it is a dead end) (no view)"
    )
    assert "coming back later costs the whole way again" in told


def test_replayed_requests_carry_the_way_back_only_where_measured() -> None:
    plain = select_request("sofa", [_candidate(3)]).inputs["candidates"]
    assert isinstance(plain, list) and set(plain[0]) == {
        "label",
        "bearing",
        "turn",
        "travel_time",
        "frontier_cells",
        "view",
    }
    told = select_request("sofa", [_candidate(3, return_time=2.25)]).inputs["candidates"]
    assert isinstance(told, list) and told[0]["return_time"] == 2.25


# ----------------------------------------------------------------------------------------------- the report


def _record(method: str, episode: int, success: int, spl: float, decisions: int) -> EpisodeRecord:
    explorer = ExplorerStats("directions", {"decisions": {"inspection": decisions}})
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
    assert plus["void_events"] >= 1 and paper["void_events"] == 0 and asked[1] < asked[0]
    assert [record.vlm_calls for record in records][1] < records[0].vlm_calls
