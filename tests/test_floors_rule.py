"""The floors' bookkeeping without a world: a floor's album spans the stay on it, the floors known from heights
(a level within the tolerance, a new one only far from every known one), and the floor rule's timing switches
(``near_frontier``: asked only with no frontier near; ``near_way``: a floor judged without the target left by a way
near)."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace
from typing import cast

import numpy as np
import pytest

from drivenav.agent.config import FloorsConfig
from drivenav.agent.context import StepContext
from drivenav.agent.explorer import Explorer
from drivenav.agent.floors import (
    LINE_AHEAD,
    LINE_BAND,
    Floor,
    Floors,
    Portal,
    StairTrip,
    _frontier_within,
    _line_heading,
    _navigable_near,
)
from drivenav.agent.handles import StepHandles
from drivenav.agent.state import BodyState
from drivenav.agent.trace import FloorDropped
from drivenav.directions.types import DirectionResult
from drivenav.grid import GridSpec
from drivenav.mapping.stairs import StairCandidate
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.semantics.protocols import FloorGuess, FloorJudgement
from drivenav.types import Action, CameraIntrinsics, Observation, Pose

H, W = 24, 32


def observation(step: int, pose: Pose | None = None) -> Observation:
    rgb = np.zeros((H, W, 3), np.uint8)
    depth = np.full((H, W), 2.0, np.float32)
    intrinsics = CameraIntrinsics.from_hfov(W, H, 79.0)
    return Observation(rgb, depth, None, pose or Pose(0.0, 0.0, 0.0), intrinsics, step, False)


def floors(config: FloorsConfig) -> Floors:
    """Floors with one floor at level 0 (no maps: the album and the levels need none)."""
    first = Floor(0.0, cast(BodyState, None), cast(Explorer, None))
    return Floors(config, first, lambda: (cast(BodyState, None), cast(Explorer, None)), lambda floor: None, 500)


def test_the_album_spans_the_whole_stay_on_a_floor_evenly() -> None:
    config = FloorsConfig(album_every=10, album_size=4)
    f = floors(config)
    for step in range(200):
        f.look(observation(step))
    steps = [view.step for view in f.floor.album]
    assert len(steps) <= config.album_size
    assert steps[0] == 0 and steps[-1] >= 120  # from the start of the stay to its late part
    gaps = np.diff(steps)
    assert (gaps == gaps[0]).all()  # evenly
    assert f.floor.album_every == gaps[0]


def test_a_level_is_known_within_its_tolerance_and_a_new_one_only_far_from_all() -> None:
    f = floors(FloorsConfig(level_tolerance=0.3, new_level=2.0))
    assert f._level_at(0.25) == 0 and f._level_at(0.35) is None
    assert not f._new_level(1.5)  # a half landing is no floor
    assert f._new_level(2.9)
    assert f._add_level(2.9) == 1
    assert f._level_at(3.1) == 1 and not f._new_level(4.0)


class Judge:
    """A reasoner that answers the floor question with ``guess`` and counts the questions."""

    def __init__(self, guess: FloorGuess) -> None:
        self.guess, self.asked = guess, 0

    def judge_floor(self, goal: str, views: object) -> FloorJudgement:
        self.asked += 1
        return FloorJudgement(self.guess, note="stub")


def frontier(x: float, y: float) -> Frontier:
    return Frontier(0, np.array([[x, y]]), np.zeros((1, 2), np.int64), (x, y), 1.0)


def step(f: Floors, judge: Judge, n: int, here: tuple[float, float], frontiers: list[Frontier]) -> bool:
    """One turn of the floor rule at step ``n``, the agent at ``here``, the floor's map with ``frontiers``."""
    state = SimpleNamespace(reasoner=judge, goal=None, planner=SimpleNamespace(reset=lambda: None))
    handles = SimpleNamespace(
        step=n,
        state=state,
        host=SimpleNamespace(goal_text="bed"),
        trace=SimpleNamespace(add=lambda event: None),
        start_segment=lambda: None,
    )
    ctx = SimpleNamespace(pose=Pose(*here, 0.0), frontiers=frontiers)
    return f.ask(cast(StepHandles, handles), cast(StepContext, ctx))


def floors_with_a_portal(config: FloorsConfig) -> Floors:
    """Floors whose first floor (no stairs on its map) knows a way up at (10, 0) to a second floor."""
    mapper = SimpleNamespace(relief=lambda: None)
    first = Floor(0.0, cast(BodyState, SimpleNamespace(mapper=mapper)), cast(Explorer, None))
    f = Floors(config, first, lambda: (cast(BodyState, None), cast(Explorer, None)), lambda floor: None, 500)
    f.floors.append(Floor(3.0, cast(BodyState, None), cast(Explorer, None)))
    f.portals.append(Portal(0, (10.0, 0.0), 0.0, 1))
    return f


def test_with_near_frontier_the_floor_question_waits_until_no_frontier_is_near() -> None:
    f, judge = floors_with_a_portal(FloorsConfig(near_frontier=2.0, near_way=0.0, min_floor_steps=100)), Judge("other")
    assert not step(f, judge, 100, (0.0, 0.0), [frontier(1.5, 0.0), frontier(8.0, 0.0)])
    assert judge.asked == 0  # a frontier 1.5 m away: not asked, and asked again at the next step
    assert step(f, judge, 101, (0.0, 0.0), [frontier(3.0, 0.0)])
    assert judge.asked == 1 and f.trip is not None and f.trip.to == 1


def test_without_near_frontier_the_question_comes_on_its_schedule() -> None:
    f, judge = floors_with_a_portal(FloorsConfig(min_floor_steps=100)), Judge("this")
    assert not step(f, judge, 100, (0.0, 0.0), [frontier(0.5, 0.0)])
    assert not step(f, judge, 101, (0.0, 0.0), [frontier(0.5, 0.0)])
    assert judge.asked == 1  # the next question at step 125
    assert not step(f, judge, 125, (0.0, 0.0), [])
    assert judge.asked == 2


def test_with_near_way_a_floor_judged_other_is_left_once_a_way_is_near() -> None:
    f, judge = floors_with_a_portal(FloorsConfig(near_way=3.0, min_floor_steps=100)), Judge("other")
    assert not step(f, judge, 100, (0.0, 0.0), [])  # judged other, the way 10 m away: explore on
    assert judge.asked == 1 and f.floor.judged_other and f.trip is None
    assert not step(f, judge, 101, (5.0, 0.0), [])
    assert step(f, judge, 102, (8.0, 0.0), [])  # looked at every step once judged: 2 m from the way, set off
    assert judge.asked == 1 and f.trip is not None


def test_the_frontier_test_measures_to_the_nearest_cell() -> None:
    ctx = cast(StepContext, SimpleNamespace(pose=Pose(0.0, 0.0, 0.0), frontiers=[frontier(3.0, 4.0)]))
    assert _frontier_within(ctx, 5.0) and not _frontier_within(ctx, 4.9) and not _frontier_within(ctx, 0.0)


def test_on_stairs_a_detour_that_collides_too_is_followed_by_one_to_the_other_side() -> None:
    """Wedged at a flight's foot: the heading collides, the open side's detour collides, so the other side next
    (not the same detour again and again until the stairs are given up)."""
    f = floors(FloorsConfig())
    trip = StairTrip(StairCandidate((0.0, 0.0), 0.0, True), None, phase="climb")
    turn = np.radians(30.0)
    handles = cast(StepHandles, SimpleNamespace(tuning=SimpleNamespace(turn=turn)))

    def drive(yaw: float, collided: bool) -> Action:
        obs = observation(0)
        obs = Observation(obs.rgb, obs.depth, None, Pose(0.0, 0.0, yaw), obs.intrinsics, 0, collided)
        return f._along(handles, obs, trip)

    assert drive(0.0, False) == Action.MOVE_FORWARD  # on the heading
    first = drive(0.0, True)  # collided without moving: a turn toward the open side
    assert first in (Action.TURN_LEFT, Action.TURN_RIGHT)
    side = 1.0 if first == Action.TURN_LEFT else -1.0
    assert drive(side * turn, False) == Action.MOVE_FORWARD  # the detour step
    assert drive(side * turn, True) == (Action.TURN_RIGHT if side > 0 else Action.TURN_LEFT)  # it collided too
    assert drive(0.0, False) == (Action.TURN_RIGHT if side > 0 else Action.TURN_LEFT)  # on to the other side
    assert drive(-side * turn, False) == Action.MOVE_FORWARD


def two_floors_judged(config: FloorsConfig) -> Floors:
    """Floors after a wrong ``other``: the first floor judged without the target, the agent on the second, which
    knows only the way back down at (10, 0) (its portal)."""
    f = floors_with_a_portal(config)
    f.floors[0].judged_other = True
    f.floors[1].state = cast(BodyState, SimpleNamespace(mapper=SimpleNamespace(relief=lambda: None)))
    f.portals.append(Portal(1, (10.0, 0.0), np.pi, 0))
    f.current = 1
    return f


def test_without_recheck_a_floor_whose_ways_lead_to_judged_floors_is_never_asked() -> None:
    f, judge = two_floors_judged(FloorsConfig(min_floor_steps=100, recheck=False)), Judge("other")
    for n in (100, 125, 150):
        assert not step(f, judge, n, (0.0, 0.0), [])
    assert judge.asked == 0 and f.trip is None


def test_with_recheck_other_on_the_second_floor_sends_the_agent_back_by_any_way() -> None:
    f, judge = two_floors_judged(FloorsConfig(min_floor_steps=100, recheck=True, near_way=3.0)), Judge("this")
    assert not step(f, judge, 100, (0.0, 0.0), [])  # asked: "this", the agent stays
    assert judge.asked == 1 and not f.floor.judged_other
    judge.guess = "other"
    assert step(f, judge, 125, (0.0, 0.0), [])  # "other" here too: back, though the way is 10 m off
    assert judge.asked == 2 and f.floor.rechecked and f.trip is not None and f.trip.to == 0


def test_back_on_the_first_floor_a_recheck_does_not_send_the_agent_up_again() -> None:
    f, judge = two_floors_judged(FloorsConfig(min_floor_steps=100, recheck=True)), Judge("other")
    f.floors[1].judged_other = f.floors[1].rechecked = True
    f.current = 0  # back where the first "other" was said
    for n in (100, 101, 125, 150):
        assert not step(f, judge, n, (9.0, 0.0), [])  # the way up is near, but its floor is judged too
    assert judge.asked == 0 and f.trip is None


def test_a_way_whose_entry_the_map_cannot_reach_rests_before_it_is_tried_again() -> None:
    config = FloorsConfig(retry_steps=40)
    f = floors_with_a_portal(config)
    way = (StairCandidate((10.0, 0.0), 0.0, True), 1)
    f.trip = StairTrip(way[0], 1)
    handles, events = trip_handles(200)
    assert f._drop(handles, "unreachable", remember=False) is None and f.trip is None
    assert not f._usable(way, 200) and not f._usable(way, 239)
    assert f._usable(way, 240)  # tried again 40 steps on
    assert f._usable((StairCandidate((12.0, 0.0), 0.0, True), 1), 200)  # another way is not resting
    assert events == [FloorDropped(200, 0, (10.0, 0.0), "unreachable")] and not f.dropped


def trip_handles(step: int) -> tuple[StepHandles, list[object]]:
    """A step's handles for the floors' trips (a goal, a planner to reset, a turn of 30 deg) and the events traced."""
    events: list[object] = []
    state = SimpleNamespace(goal=None, planner=SimpleNamespace(reset=lambda: None))
    tuning = SimpleNamespace(turn=np.radians(30.0))
    handles = SimpleNamespace(step=step, state=state, tuning=tuning, trace=SimpleNamespace(add=events.append))
    return cast(StepHandles, handles), events


def test_a_way_not_reached_within_approach_steps_is_dropped_for_good_and_traced() -> None:
    f = floors_with_a_portal(FloorsConfig(approach_steps=150))
    way = StairCandidate((10.0, 0.0), 0.0, True)
    f.trip = StairTrip(way, 1, steps=150)
    handles, events = trip_handles(321)
    assert f.heading_for_stairs(handles, observation(321), cast(StepContext, None)) is None and f.trip is None
    assert f.dropped == [way] and not f._usable((way, 1), 10_000)
    assert events == [FloorDropped(321, 0, (10.0, 0.0), "approach_steps")]


def test_stairs_given_up_between_levels_are_dropped_and_the_agent_turns_back() -> None:
    """Past ``climb_steps`` on a flight (off the level, no level reached): the way is dropped for good and traced,
    and the trip goes on back down it, toward the floor the agent left."""
    f = floors_with_a_portal(FloorsConfig(climb_steps=120))
    way = StairCandidate((10.0, 0.0), 0.0, True)
    f.trip = StairTrip(way, 1, phase="climb", steps=120, left_level=True, last_height=1.5)
    handles, events = trip_handles(400)
    on_flight = replace(observation(400), pose=Pose(11.0, 0.0, 0.0, z=1.5))
    assert f.climb(handles, on_flight) in (Action.TURN_LEFT, Action.TURN_RIGHT)  # about: back down the flight
    assert f.trip is not None and f.trip.to == 0 and not f.trip.way.up and f.dropped == [way]
    assert events == [FloorDropped(400, 0, (10.0, 0.0), "climb_steps")]


def test_an_entry_with_no_floor_behind_it_sets_out_from_the_nearest_navigable_point() -> None:
    """At the top of a flight the strip of floor behind the way back down can be all inflation: the navigable
    point nearest the entry in any direction is the place to set out from (else the agent set off at every
    step and never went)."""
    grid = GridSpec(0.05, (0.0, 0.0), (40, 40))
    navigable = np.zeros((40, 40), np.bool_)
    navigable[:, 30:] = True  # floor only to the east, from x = 1.5 m
    snapshot = MapSnapshot(grid, ~navigable, navigable, navigable)
    ctx = StepContext(Pose(2.0, 1.0, 0.0), snapshot, [], cast(DirectionResult, SimpleNamespace(directions=[])), None)
    down_west = StairCandidate((1.0, 1.0), 0.0, False)  # heading east: "back" is west, where there is no floor
    point = _navigable_near(ctx, down_west)
    assert point is not None and abs(point[0] - 1.525) < 1e-9 and abs(point[1] - 1.0) < 0.03
    assert _navigable_near(ctx, StairCandidate((-1.0, 1.0), 0.0, False)) is None  # 2.5 m from any floor


def test_at_a_suspected_way_the_agent_drives_on_faces_along_the_railing_and_goes_on() -> None:
    """A way suspected behind a railing (agent.floors.railings): from where the map let the agent get, it drives on
    toward the point to look from (off the map's navigable floor), faces the way's heading, and the trip ends with
    the place looked from remembered and traced; a suspect near it is not looked at again."""
    f = floors(FloorsConfig(railings=True, look_steps=6))
    suspect = StairCandidate((1.0, 0.0), np.pi, False, seen=False)
    f.trip = StairTrip(suspect, None, phase="turn")
    events: list[object] = []
    state = SimpleNamespace(goal=None, planner=SimpleNamespace(reset=lambda: None))
    handles = cast(
        StepHandles,
        SimpleNamespace(
            step=7, tuning=SimpleNamespace(turn=np.radians(30.0)), trace=SimpleNamespace(add=events.append), state=state
        ),
    )
    obs = observation(0)

    def at(x: float, yaw: float) -> Action | None:
        o = Observation(obs.rgb, obs.depth, None, Pose(x, 0.0, yaw), obs.intrinsics, 0, False)
        assert f.trip is not None
        return f._look(handles, o, f.trip)

    assert at(0.0, 0.0) == Action.MOVE_FORWARD and at(0.25, 0.0) == Action.MOVE_FORWARD  # on toward (1, 0)
    assert at(0.5, 0.0) in (Action.TURN_LEFT, Action.TURN_RIGHT)  # near enough: face back along the railing
    for k in range(1, 6):
        assert at(0.5, k * np.radians(30.0)) == Action.TURN_LEFT
    assert at(0.5, np.pi) is None and f.trip is None  # faced: the trip ends, the explorer acts
    assert f.looked == [(1.0, 0.0)] and [type(e).__name__ for e in events] == ["FloorLooked"]
    assert not f._unlooked(StairCandidate((1.4, 0.3), np.pi, False, seen=False))
    assert f._unlooked(StairCandidate((3.0, 0.0), np.pi, False, seen=False))


def test_before_the_stairs_the_agent_steers_back_to_the_flights_centre_line() -> None:
    """A flight from (1, 2) heading +y (its centre line x = 1): within LINE_BAND of the line the way's heading; farther
    to one side, toward the point LINE_AHEAD ahead on the line; once off the level, the way's heading alone."""
    trip = StairTrip(StairCandidate((1.0, 2.0), math.pi / 2, up=True), to=None)

    def heading(x: float, y: float) -> float:
        return _line_heading(observation(0, Pose(x, y, 0.0)), trip)

    assert LINE_BAND == 0.1 and LINE_AHEAD == 0.5
    assert heading(1.05, 1.0) == math.pi / 2  # 5 cm right of the line: on it
    assert heading(0.7, 1.0) == pytest.approx(math.pi / 2 - math.atan2(0.3, 0.5))  # 0.3 m left: 31 degrees right
    assert heading(1.3, 1.0) == pytest.approx(math.pi / 2 + math.atan2(0.3, 0.5))
    assert heading(0.7, 3.0) == pytest.approx(math.pi / 2 - math.atan2(0.3, 0.5))  # past the entry alike
    trip.left_level = True
    assert heading(0.7, 3.0) == math.pi / 2
