"""Representative views and forward-240 deg sweeps (Sec. IV-A c): hand-computed turn counts and orders."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.directions.types import Direction
from drivenav.grid import wrap_angle
from drivenav.inspection import (
    RepresentativeViews,
    full_scan_turns,
    needs_inspection,
    plan_sweep,
    sweep_turns,
    turn_toward,
)
from drivenav.inspection.views import forward_of
from drivenav.packing import DeferredImage, PackedImage
from drivenav.paper import InspectionConfig
from drivenav.types import Action, CameraIntrinsics, Observation, Pose

TURN = math.radians(30.0)
FORWARD = InspectionConfig()
ALL_AROUND = InspectionConfig(restrict_forward=False)


def rad(*degrees: float) -> list[float]:
    return [math.radians(d) for d in degrees]


def deg(yaws: list[float]) -> list[float]:
    return [round(math.degrees(y), 6) for y in yaws]


def direction(label: int, bearing_deg: float) -> Direction:
    bearing = math.radians(bearing_deg) % (2.0 * math.pi)
    pts = np.zeros((1, 2))
    return Direction(label, bearing, (label,), (bearing,), pts, pts, (0.0, 0.0))


def observation(yaw: float, step: int = 0) -> Observation:
    intrinsics = CameraIntrinsics.from_hfov(4, 3, 79.0)
    rgb = np.full((3, 4, 3), step, dtype=np.uint8)
    depth = np.ones((3, 4), dtype=np.float32)
    return Observation(rgb, depth, None, Pose(0.0, 0.0, wrap_angle(yaw)), intrinsics, step, False)


def execute(heading: float, yaws: list[float], views: RepresentativeViews, directions: list[Direction]) -> int:
    """Drive the sweep with :func:`turn_toward`, observing every frame; returns the turns taken."""
    yaw, turns = heading, 0
    views.observe(directions, observation(yaw), 0)
    for target in yaws:
        while (action := turn_toward(yaw, target, TURN)) is not None:
            yaw += TURN if action == Action.TURN_LEFT else -TURN
            turns += 1
            views.observe(directions, observation(yaw, turns), turns)
    return turns


# --- plan_sweep: hand-computed cases -------------------------------------------------------------------------


def test_single_direction_at_plus_70_takes_two_left_turns() -> None:
    heading = math.radians(100.0)
    yaws = plan_sweep(heading, rad(170.0), TURN)
    assert deg(yaws) == [160.0]
    assert sweep_turns(heading, yaws, TURN) == 2
    assert turn_toward(heading, yaws[0], TURN) == Action.TURN_LEFT
    views = RepresentativeViews()
    execute(heading, yaws, views, [direction(7, 170.0)])
    assert views.get(7) is not None
    assert views.get(7).error == pytest.approx(math.radians(10.0))  # type: ignore[union-attr]


def test_left_first_when_its_initial_turn_is_smaller() -> None:
    yaws = plan_sweep(0.0, rad(30.0, -60.0), TURN)
    assert deg(yaws) == [30.0, -60.0]
    assert sweep_turns(0.0, yaws, TURN) == 1 + 3


def test_right_first_when_its_initial_turn_is_smaller() -> None:
    yaws = plan_sweep(0.0, rad(60.0, -30.0), TURN)
    assert deg(yaws) == [-30.0, 60.0]
    assert sweep_turns(0.0, yaws, TURN) == 1 + 3


def test_sweeps_outward_on_the_first_side_then_crosses_inner_first() -> None:
    # Left nearest 40 < right nearest 50: 30, 90 on the left, then -60 (1 + 2 + 5 turns).
    yaws = plan_sweep(0.0, rad(100.0, -50.0, 40.0), TURN)
    assert deg(yaws) == [30.0, 90.0, -60.0]
    assert sweep_turns(0.0, yaws, TURN) == 8
    # Adding -20 makes the right side nearer: -30, -60, then 30, 90 (1 + 1 + 3 + 2 turns).
    yaws = plan_sweep(0.0, rad(100.0, -50.0, 40.0, -20.0), TURN)
    assert deg(yaws) == [-30.0, -60.0, 30.0, 90.0]
    assert sweep_turns(0.0, yaws, TURN) == 7


def test_bearings_straddling_zero() -> None:
    heading = math.radians(350.0)  # bearings 20 and 300 deg: alpha = +30 and -50
    yaws = plan_sweep(heading, rad(20.0, 300.0), TURN)
    assert deg(yaws) == [20.0, -70.0]  # 350 + 30 and 350 - 60, wrapped to (-180, 180]
    assert sweep_turns(heading, yaws, TURN) == 1 + 3


def test_nothing_to_do() -> None:
    assert plan_sweep(0.3, [], TURN) == []
    assert plan_sweep(0.3, [0.3 + math.radians(14.0), 0.3 - math.radians(15.0)], TURN) == []
    assert sweep_turns(0.3, [], TURN) == 0


def test_half_way_bearing_is_served_by_the_nearer_yaw() -> None:
    # 45 deg lies exactly 15 deg from both 30 and 60: the tolerance is inclusive and the smaller turn wins.
    assert deg(plan_sweep(0.0, rad(45.0), TURN)) == [30.0]
    assert deg(plan_sweep(0.0, rad(-45.0), TURN)) == [-30.0]
    # ... unless an outer bearing needs 60 anyway: one stop serves both.
    assert deg(plan_sweep(0.0, rad(45.0, 60.0), TURN)) == [60.0]
    views = RepresentativeViews()
    assert views.observe([direction(1, 45.0)], observation(math.radians(30.0)), 1) == [(1, False)]


def test_one_stop_serves_several_bearings() -> None:
    yaws = plan_sweep(0.0, rad(50.0, 65.0, 70.0), TURN)
    assert deg(yaws) == [60.0]
    assert sweep_turns(0.0, yaws, TURN) == 2


def test_second_side_bearings_served_by_the_first_side_need_no_stop() -> None:
    # All-around mode: -170 (right, nearer) is faced at 180 deg, which also serves +175.
    yaws = plan_sweep(0.0, rad(175.0, -170.0), TURN)
    assert deg(yaws) == [180.0]
    assert sweep_turns(0.0, yaws, TURN) == 6


def test_turn_toward() -> None:
    assert turn_toward(0.0, math.radians(20.0), TURN) == Action.TURN_LEFT
    assert turn_toward(0.0, math.radians(-20.0), TURN) == Action.TURN_RIGHT
    assert turn_toward(0.0, math.radians(15.0), TURN) is None
    assert turn_toward(math.radians(175.0), math.radians(-175.0), TURN) is None
    assert turn_toward(math.radians(170.0), math.radians(-150.0), TURN) == Action.TURN_LEFT  # across +-180
    assert turn_toward(0.0, math.pi, TURN) == Action.TURN_LEFT


def test_full_scan_is_twelve_turns() -> None:
    assert full_scan_turns(TURN) == 12
    assert full_scan_turns(math.radians(25.0)) == 15


# --- needs_inspection ------------------------------------------------------------------------------------------


def test_direction_behind_only_in_the_all_around_ablation() -> None:
    behind, ahead = direction(1, 150.0), direction(2, 60.0)
    views = RepresentativeViews()
    assert needs_inspection([behind, ahead], views, 0.0, FORWARD) == [ahead]
    assert needs_inspection([behind, ahead], views, 0.0, ALL_AROUND) == [behind, ahead]
    assert deg(plan_sweep(0.0, [behind.bearing], TURN)) == [150.0]


def test_forward_range_boundary_and_existing_views() -> None:
    edge, past = direction(1, -120.0), direction(2, 121.0)
    views = RepresentativeViews()
    assert needs_inspection([edge, past], views, 0.0, FORWARD) == [edge]
    views.observe([edge], observation(math.radians(-120.0)), 0)
    assert needs_inspection([edge, past], views, 0.0, FORWARD) == []


def test_forward_of_keeps_the_240_deg_around_a_heading_across_the_wrap() -> None:
    """Heading 170 deg: bearings 180 (10 off), -70 (120 off: the edge) and 50 (-120 off) are forward; -69 (121
    off) and 0 (-170 off) are not."""
    bearings = {1: 180.0, 2: -70.0, 3: -69.0, 4: 50.0, 5: 0.0}
    directions = [direction(label, bearing) for label, bearing in bearings.items()]
    forward = forward_of(directions, math.radians(170.0), FORWARD.forward_range)
    assert [d.label for d in forward] == [1, 2, 4]


# --- RepresentativeViews ---------------------------------------------------------------------------------------


def test_view_replaced_only_when_the_error_shrinks() -> None:
    views = RepresentativeViews()
    d = [direction(3, 40.0)]
    assert views.observe(d, observation(math.radians(30.0), 1), 1) == [(3, False)]  # error 10
    assert views.observe(d, observation(math.radians(52.0), 2), 2) == []  # error 12
    assert views.observe(d, observation(math.radians(50.0), 3), 3) == []  # error 10: a tie keeps the old view
    stored = views.get(3)
    assert stored is not None and stored.step == 1 and stored.pose.yaw == pytest.approx(math.radians(30.0))
    assert views.observe(d, observation(math.radians(45.0), 4), 4) == [(3, True)]  # error 5
    stored = views.get(3)
    assert stored is not None
    assert (stored.step, stored.label, int(stored.rgb[0, 0, 0])) == (4, 3, 4)
    assert stored.error == pytest.approx(math.radians(5.0))
    assert stored.bearing == pytest.approx(math.radians(40.0))


def test_observe_records_nothing_out_of_tolerance() -> None:
    views = RepresentativeViews()
    ds = [direction(1, 20.0), direction(2, -40.0), direction(3, 180.0), direction(4, 15.5)]
    assert views.observe(ds, observation(0.0), 0) == []
    assert views.labels() == set()
    assert not views.has_view(1) and views.get(1) is None


def test_observe_records_every_direction_in_tolerance_across_zero() -> None:
    views = RepresentativeViews()
    ds = [direction(1, 355.0), direction(2, 8.0), direction(5, 90.0)]
    assert views.observe(ds, observation(math.radians(2.0)), 0) == [(1, False), (2, False)]
    assert views.labels() == {1, 2}


def test_stored_views_hold_their_frame_packed_once_and_read_back_exactly() -> None:
    views = RepresentativeViews()
    rng = np.random.default_rng(4)
    rgb = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    semantic = rng.integers(-1, 40, (48, 64), dtype=np.int32)
    frame = dataclasses.replace(observation(0.0), rgb=rgb, semantic=semantic)
    assert views.observe([direction(1, 5.0), direction(2, -10.0)], frame, 7) == [(1, False), (2, False)]
    one, two = views.get(1), views.get(2)
    assert one is not None and two is not None
    assert isinstance(one._rgb, PackedImage) and one._rgb is two._rgb  # one compressed copy for both directions
    assert one._semantic is two._semantic
    for view in (one, two):
        assert view.rgb.dtype == np.uint8 and np.array_equal(view.rgb, rgb)
        assert view.semantic is not None and view.semantic.dtype == np.int32 and np.array_equal(view.semantic, semantic)
        assert not np.shares_memory(view.rgb, rgb)  # the observation's frame is not kept alive
    assert (one.step, one.bearing, two.error) == (
        7,
        pytest.approx(math.radians(5.0)),
        pytest.approx(math.radians(10.0)),
    )


def test_a_deferred_rgb_image_is_stored_unrendered_and_rendered_on_each_read() -> None:
    rgb = np.random.default_rng(5).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    renders: list[int] = []

    def render() -> np.ndarray:
        renders.append(1)
        return rgb.copy()

    eager = observation(0.0, 2)
    frame = Observation.deferred(render, eager.depth, eager.semantic, eager.pose, eager.intrinsics, 2, False)
    views = RepresentativeViews()
    assert views.observe([direction(1, 5.0), direction(2, -10.0)], frame, 2) == [(1, False), (2, False)]
    one, two = views.get(1), views.get(2)
    assert one is not None and two is not None
    assert isinstance(one._rgb, DeferredImage) and one._rgb is two._rgb and not renders  # nothing rendered yet
    assert np.array_equal(one.rgb, rgb) and not one.rgb.flags.writeable and len(renders) == 2  # each read renders
    assert np.array_equal(frame.rgb, rgb)  # the observation itself still renders its own image


def test_inherited_view_shares_the_parents_packed_frame() -> None:
    views = RepresentativeViews()
    views.observe([direction(1, 0.0), direction(2, 25.0)], observation(math.radians(20.0), 3), 3)
    assert views.inherit(9, [1, 2], math.radians(18.0))
    child, parent = views.get(9), views.get(2)
    assert child is not None and parent is not None
    assert child._rgb is parent._rgb and (child.label, child.step) == (9, 3)
    assert child.error == pytest.approx(math.radians(2.0)) and child.bearing == pytest.approx(math.radians(18.0))


def test_retain_and_reset() -> None:
    views = RepresentativeViews()
    views.observe([direction(1, 0.0), direction(2, 5.0), direction(3, -5.0)], observation(0.0), 0)
    views.retain([2, 3, 9])
    assert views.labels() == {2, 3}
    views.reset()
    assert views.labels() == set()


# --- properties ------------------------------------------------------------------------------------------------

headings = st.floats(-math.pi, math.pi)
forward_offsets = st.lists(st.floats(-120.0, 120.0), max_size=8)
any_offsets = st.lists(st.floats(-180.0, 180.0), max_size=8)


@settings(max_examples=150, deadline=None)
@given(headings, forward_offsets)
def test_forward_sweep_never_costs_more_than_a_full_scan(heading: float, offsets: list[float]) -> None:
    yaws = plan_sweep(heading, [heading + a for a in rad(*offsets)], TURN)
    assert sweep_turns(heading, yaws, TURN) <= full_scan_turns(TURN)


@settings(max_examples=150, deadline=None)
@given(headings, any_offsets)
def test_executed_sweep_records_every_requested_view(heading: float, offsets: list[float]) -> None:
    directions = [direction(i, math.degrees(heading) + a) for i, a in enumerate(offsets)]
    yaws = plan_sweep(heading, [d.bearing for d in directions], TURN)
    for y in yaws:  # reachable by whole turns
        k = wrap_angle(y - heading) / TURN
        assert k == pytest.approx(round(k), abs=1e-9)
    assert len({round(math.degrees(wrap_angle(y - heading))) % 360 for y in yaws}) == len(yaws)  # no repeated stop
    views = RepresentativeViews()
    assert execute(heading, yaws, views, directions) == sweep_turns(heading, yaws, TURN)
    assert views.labels() == {d.label for d in directions}


@settings(max_examples=100, deadline=None)
@given(headings, any_offsets)
def test_full_scan_records_every_direction(heading: float, offsets: list[float]) -> None:
    directions = [direction(i, math.degrees(heading) + a) for i, a in enumerate(offsets)]
    views = RepresentativeViews()
    yaw = heading
    for turn in range(full_scan_turns(TURN) + 1):
        views.observe(directions, observation(yaw, turn), turn)
        yaw += TURN
    assert views.labels() == {d.label for d in directions}
    assert all(v.error <= math.radians(15.0) + 1e-9 for v in map(views.get, views.labels()) if v is not None)
