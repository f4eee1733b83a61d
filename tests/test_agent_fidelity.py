"""The agent against the paper: which directions a decision offers, labels carried over relabellings,
unreachable targets set aside rather than rejected, the decision counters and the segmentation-free revisits."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from agent_scenes import episode_for, t_junction
from drivenav.agent.base import ExplorerCounters
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.decision import candidates
from drivenav.agent.explorers.drive_nav.explorer import DirectionsExplorer
from drivenav.agent.explorers.drive_nav.memory import Directions
from drivenav.agent.explorers.drive_nav.relabel import carry_over
from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import DirectionSelected, InspectionStarted, Trace, of_type
from drivenav.agents import make_agent
from drivenav.directions.tracking import DirectionTracker
from drivenav.directions.types import Direction, DirectionResult, TrackingUpdate
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord, missed_cause
from drivenav.eval.runner import run_episode
from drivenav.inspection.views import RepresentativeViews
from drivenav.metrics import retraced
from drivenav.paper import DirectionConfig
from drivenav.semantics.embedded import EmbeddedReasoner
from drivenav.semantics.protocols import Detection, View
from drivenav.settings import load_settings
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose, SimConfig
from test_directions_tracking import BLUE, PINK, RED, YELLOW, cluster

SIM = SimConfig()


# ----------------------------------------------------------------------------------------------- tracking


def test_tracking_reports_created_merged_and_removed_labels_of_fig3() -> None:
    tracker = DirectionTracker(DirectionConfig())
    tracker.update([cluster(30, BLUE), cluster(80, RED), cluster(200, YELLOW)])
    assert tracker.last_update == TrackingUpdate(created=(0, 1, 2))
    tracker.update([cluster(55, BLUE, RED), cluster(205, YELLOW), cluster(250, PINK)])
    assert tracker.last_update == TrackingUpdate(created=(4,), merged={3: (0, 1)})
    tracker.update([cluster(55, BLUE, RED)])  # yellow and pink are gone
    assert tracker.last_update == TrackingUpdate(removed=(2, 4))


# ----------------------------------------------------------------------------------------------- views


def _view(label: int, yaw_deg: float) -> View:
    image = np.zeros((2, 2, 3), np.uint8)
    pose = Pose(0.0, 0.0, math.radians(yaw_deg))
    return View(label, image, None, pose, pose.yaw, 0.0, 0)


def test_a_relabelled_direction_inherits_the_parent_view_facing_it_best() -> None:
    views = RepresentativeViews()
    views._views = {0: _view(0, 0.0), 1: _view(1, 40.0)}
    assert views.inherit(3, (0, 1), math.radians(30.0))
    inherited = views.get(3)
    assert inherited is not None and inherited.label == 3
    assert inherited.pose.yaw == pytest.approx(math.radians(40.0))
    assert inherited.error == pytest.approx(math.radians(10.0))
    assert not views.inherit(3, (0,), 0.0)  # a direction with a view keeps it
    assert not views.inherit(4, (7,), 0.0)  # no parent view, nothing to inherit


# ----------------------------------------------------------------------------------------------- candidates


def _direction(label: int, bearing_deg: float) -> Direction:
    point = np.array([[math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg))]]) * (2 + label)
    far = (float(point[0, 0]), float(point[0, 1]))
    return Direction(label, math.radians(bearing_deg), (label,), (math.radians(bearing_deg),), point, point, far)


def _agent_at(name: str, bearings_deg: dict[int, float], heading_deg: float) -> tuple[ExplorerAgent, StepContext]:
    agent = make_agent(load_settings(name))
    assert isinstance(agent, ExplorerAgent)
    agent.reset("chair", 0, GroundTruth({}, VOCABULARY))
    directions = tuple(_direction(label, b) for label, b in sorted(bearings_deg.items()))
    pose = Pose(0.0, 0.0, math.radians(heading_deg))
    ctx = StepContext(pose, None, [], DirectionResult(directions, {}, ()), None)  # type: ignore[arg-type]
    _state(agent).views._views = {d.label: _view(d.label, math.degrees(d.bearing)) for d in directions}
    return agent, ctx


def _state(agent: ExplorerAgent) -> Directions:
    """The directions explorer's memory of the running episode."""
    assert isinstance(agent.explorer, DirectionsExplorer)
    return agent.explorer.memory


def _offered(agent: ExplorerAgent, ctx: StepContext, reason: str) -> list[int]:
    return [c.label for c in candidates(_state(agent), agent.handles(), ctx, reason)]


AROUND = {0: 0.0, 1: 90.0, 2: 120.0, 3: 150.0, 4: 180.0, 5: -100.0, 6: -130.0}


def test_decisions_after_the_start_scan_offer_only_the_forward_240_degrees() -> None:
    agent, ctx = _agent_at("drive-nav", AROUND, 0.0)
    assert _offered(agent, ctx, "scan") == list(AROUND)  # the start scan saw everything
    assert _offered(agent, ctx, "vanished") == [0, 1, 2, 5]  # |alpha| <= 120 deg
    _state(agent).event_heading = math.radians(180.0)  # an inspection event measures alpha from where it began
    assert _offered(agent, ctx, "inspection") == [1, 2, 3, 4, 5, 6]  # all but 0 deg
    assert _state(agent).counts.dead_end_decisions == 0


def test_a_dead_end_offers_the_rear_range() -> None:
    agent, ctx = _agent_at("drive-nav", {0: 170.0, 1: -160.0}, 0.0)
    assert _offered(agent, ctx, "vanished") == [0, 1]
    assert _state(agent).counts.dead_end_decisions == 1


@pytest.mark.parametrize("name", ["no-240", "direction-360"])
def test_360_methods_decide_among_every_direction(name: str) -> None:
    agent, ctx = _agent_at(name, AROUND, 0.0)
    assert _offered(agent, ctx, "inspection") == list(AROUND)


def test_a_merged_followed_direction_is_still_followed_without_a_decision() -> None:
    agent, ctx = _agent_at("drive-nav", {0: 10.0, 1: 40.0}, 0.0)
    _state(agent).selected, _state(agent).inspected = 0, {0, 1}
    carry_over(_state(agent), agent.handles(), ctx)
    merged = Direction(2, math.radians(25.0), (0, 1), (), np.zeros((1, 2)), np.zeros((1, 2)), (3.0, 1.0))
    result = DirectionResult((merged,), {}, (), tracking=TrackingUpdate(merged={2: (0, 1)}))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], result, None))  # type: ignore[arg-type]
    episode = _state(agent)
    assert episode.selected == 2 and 2 in episode.inspected and episode.views.has_view(2)
    stats = _state(agent).counts
    assert (stats.followed_through_relabel, stats.selected_lost, stats.labels_merged) == (1, 0, 1)


def test_a_direction_back_at_a_removed_ones_place_keeps_its_inspected_state() -> None:
    agent, ctx = _agent_at("drive-nav", {0: 10.0, 1: 90.0}, 0.0)
    _state(agent).inspected = {0, 1}
    carry_over(_state(agent), agent.handles(), ctx)
    gone = DirectionResult((ctx.directions[0],), {}, (), tracking=TrackingUpdate(removed=(1,)))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], gone, None))  # type: ignore[arg-type]
    again = _direction(1, 90.0)
    back = Direction(5, again.bearing, (1,), (), again.waypoints, again.points, again.farthest_point)
    result = DirectionResult((ctx.directions[0], back), {}, (), tracking=TrackingUpdate(created=(5,)))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], result, None))  # type: ignore[arg-type]
    assert 5 in _state(agent).inspected
    assert _state(agent).counts.labels_reidentified == 1


# ----------------------------------------------------------------------------------------------- targets


class _Everything:
    name = "everything"

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        pass

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        assert observation.semantic is not None
        return [Detection(observation.semantic == 1, 0.9, phrase)]


def _frame(step: int) -> Observation:
    semantic = np.zeros((48, 64), dtype=np.int32)
    semantic[20:40, 20:44] = 1
    depth = np.full((48, 64), 2.0, dtype=np.float32)
    intrinsics = CameraIntrinsics.from_hfov(64, 48, 79.0)
    return Observation(np.zeros((48, 64, 3), np.uint8), depth, semantic, Pose(0.0, 0.0, 0.0), intrinsics, step, False)


def test_a_target_set_aside_comes_back_and_is_never_rejected() -> None:
    reasoner = EmbeddedReasoner()
    truth = GroundTruth({1: "chair"}, VOCABULARY)
    reasoner.begin_episode("chair", truth)
    search = TargetSearch(SIM, SearchConfig(verify=False), _Everything(), reasoner)
    search.begin("chair")
    trace = Trace()
    search.observe(_frame(0), trace)
    target = search.current()
    assert target is not None
    search.set_aside(target.candidate_id, 10, trace)
    search.observe(_frame(5), trace)
    assert search.current() is None and not search.objects.rejected()
    search.observe(_frame(11), trace)
    current = search.current()
    assert current is not None and current.candidate_id == target.candidate_id
    assert search.outcome() == (1, 1, 1)
    assert [e.kind for e in trace.events].count("target_set_aside") == 1


def _missed(**decisions: int) -> EpisodeRecord:
    record = EpisodeRecord("e", "s", "chair", "drive-nav", 500, 0, "timeout", "missed_target", success=0)
    return EpisodeRecord.from_json({**record.to_json(), **decisions})


def test_missed_targets_are_broken_down_by_what_the_agent_did() -> None:
    assert missed_cause(_missed()) == "never_detected"
    assert missed_cause(_missed(target_candidates=2, targets_set_aside=1, targets_accepted=1)) == (
        "set_aside_unreachable"
    )
    assert missed_cause(_missed(target_candidates=1, targets_accepted=1)) == "accepted_not_reached"
    rejected = {"target_candidates": 1, "verifications": {"rejected": 1}}
    assert missed_cause(EpisodeRecord.from_json({**_missed().to_json(), **rejected})) == "rejected_by_verification"
    assert missed_cause(_missed(target_candidates=1)) == "detected_not_accepted"


def test_records_carry_the_explorer_counters_and_read_older_schemas() -> None:
    counters = {"inspection_events": 3, "labels_created": 7, "decisions": {"scan": 1, "inspection": 2}}
    record = replace(_missed(target_candidates=1), explorer=ExplorerCounters("directions", counters))
    data = record.to_json()
    assert data["schema_version"] == 5 and data["target_candidates"] == 1  # the body's counters flat ...
    assert data["explorer"] == {"name": "directions", "counters": counters}  # ... the explorer's under its name
    assert EpisodeRecord.from_json(json.loads(json.dumps(data))) == record
    schema_4 = {k: v for k, v in data.items() if k != "explorer"} | {"schema_version": 4, "inspection_events": 3}
    schema_4 |= {"labels_created": 7, "decisions_by_reason": {"scan": 1, "inspection": 2}, "labels_merged": 0}
    old = EpisodeRecord.from_json(schema_4)  # the flat DRIVE-Nav counters become the method's explorer's
    assert old.explorer == ExplorerCounters("directions", {**counters, "labels_merged": 0}) and old.body == record.body
    greedy = EpisodeRecord.from_json({**schema_4, "agent": "nearest-frontier"})
    assert greedy.explorer is not None and greedy.explorer.name == "greedy"
    assert EpisodeRecord.from_json({**schema_4, "agent": "oracle"}).explorer is None
    bare = {k: v for k, v in schema_4.items() if k not in ("inspection_events", "labels_created", "retraced_m")}
    assert EpisodeRecord.from_json({**bare, "schema_version": 2}).explorer == ExplorerCounters(
        "directions", {"decisions": {"scan": 1, "inspection": 2}, "labels_merged": 0}
    )
    before_traces = {k: v for k, v in schema_4.items() if k != "trace"}
    assert EpisodeRecord.from_json({**before_traces, "schema_version": 3}).trace == ""
    with pytest.raises(InputError, match=r"record\.explorer\.counters"):
        EpisodeRecord.from_json({**data, "explorer": {"name": "directions", "counters": {"decisions": "many"}}})


# ----------------------------------------------------------------------------------------------- revisits


def _line(*xs: float) -> np.ndarray:
    return np.array([[x, 0.0] for x in xs])


def test_retraced_counts_an_out_and_back_corridor_once() -> None:
    out_and_back = _line(*np.arange(0.0, 10.01, 0.25), *np.arange(9.75, -0.01, -0.25))
    stretches, metres = retraced(out_and_back)
    assert stretches == 1
    # Back from x = 10: the move 10 -> 9.75 has its midpoint 0.875 m from the path driven > 1 m earlier (x <= 9);
    # every later move lies within 0.5 m of it: 39 moves of 0.25 m.
    assert metres == pytest.approx(9.75)


def test_retraced_ignores_short_returns_turns_and_straight_paths() -> None:
    assert retraced(_line(*np.arange(0.0, 10.01, 0.25))) == (0, 0.0)
    stretches, metres = retraced(_line(*np.arange(0.0, 3.01, 0.25), *np.arange(2.75, -0.01, -0.25)))
    assert stretches == 0 and metres == pytest.approx(2.75)  # retraced, but shorter than 5 m
    turning = np.repeat(_line(*np.arange(0.0, 10.01, 0.25), *np.arange(9.75, -0.01, -0.25)), 2, axis=0)
    assert retraced(turning) == retraced(_line(*np.arange(0.0, 10.01, 0.25), *np.arange(9.75, -0.01, -0.25)))


# ----------------------------------------------------------------------------------------------- end to end


def test_an_episode_record_accounts_for_every_step_and_decision() -> None:
    scene = t_junction(target_on_left=True)
    env = EmbeddedEnv(lambda _: scene, SIM)
    agent = make_agent(load_settings("drive-nav"))
    record, trace = run_episode(env, agent, episode_for(scene, (12.0, 2.5), math.pi / 2, "plant", ""), 0, 500)
    steps, explorer = record.body.steps_by_activity, record.explorer
    assert sum(steps.values()) == record.steps and steps["start_scan"] == 12
    assert explorer is not None and explorer.name == "directions"
    decisions = explorer.counters["decisions"]
    assert isinstance(decisions, dict) and decisions["scan"] == 1
    assert sum(decisions.values()) == len(of_type(trace.events, DirectionSelected))
    assert explorer.counters["inspection_events"] == len(of_type(trace.events, InspectionStarted))
    assert explorer.counters["labels_created"] >= 1 and record.retraced_revisits == 0


def test_a_split_off_branch_is_new_but_a_flickering_one_is_not() -> None:
    agent, ctx = _agent_at("drive-nav", {0: 10.0, 1: 40.0}, 0.0)
    _state(agent).inspected = {0, 1}
    carry_over(_state(agent), agent.handles(), ctx)
    merged = Direction(
        2,
        math.radians(25.0),
        (0, 1),
        (),
        np.vstack([d.waypoints for d in ctx.result.directions]),
        np.zeros((1, 2)),
        (3.0, 1.0),
    )
    result = DirectionResult((merged,), {}, (), tracking=TrackingUpdate(merged={2: (0, 1)}))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], result, None))  # type: ignore[arg-type]
    flicker = Direction(3, math.radians(40.0), (1,), (), ctx.directions[1].waypoints, np.zeros((1, 2)), (3.0, 2.0))
    result = DirectionResult((merged, flicker), {}, (), tracking=TrackingUpdate(created=(3,)))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], result, None))  # type: ignore[arg-type]
    assert 3 in _state(agent).inspected  # label 1 again, split off the merge a step later
    branch = _direction(4, -60.0)  # a branch at a place no retired direction held
    result = DirectionResult((merged, flicker, branch), {}, (), tracking=TrackingUpdate(created=(4,)))
    carry_over(_state(agent), agent.handles(), StepContext(ctx.pose, None, [], result, None))  # type: ignore[arg-type]
    assert 4 not in _state(agent).inspected and _state(agent).counts.labels_reidentified == 1
