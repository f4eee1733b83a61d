"""Temporal association of directions: position-based merge, angular association, label stability."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from drivenav.directions.tracking import DirectionTracker, coinciding, waypoints_coincide
from drivenav.directions.types import Cluster
from drivenav.paper import DirectionConfig


def cluster(bearing_deg: float, *waypoints: tuple[float, float]) -> Cluster:
    pts = np.array(waypoints, dtype=np.float64).reshape(-1, 2)
    ids = tuple(range(len(waypoints)))
    far = (float(pts[0, 0]), float(pts[0, 1]))
    return Cluster(math.radians(bearing_deg), ids, (math.radians(bearing_deg),) * len(ids), pts, pts, far)


def labels_by_bearing(directions: tuple[object, ...]) -> dict[int, int]:
    return {round(math.degrees(d.bearing)): d.label for d in directions}  # type: ignore[attr-defined]


BLUE, RED, YELLOW, PINK = (3.0, 2.0), (1.0, 3.0), (-3.0, -1.0), (-1.0, -3.0)


def test_paper_fig3_panels_4_to_5_merge_and_split() -> None:
    tracker = DirectionTracker(DirectionConfig())
    first = tracker.update([cluster(30, BLUE), cluster(80, RED), cluster(200, YELLOW)])
    assert labels_by_bearing(first) == {30: 0, 80: 1, 200: 2}
    # Blue and red now fall within 45 degrees: one cluster holding both waypoints -> both labels retired.
    # Yellow reveals an additional bearing that forms a new (pink) direction.
    second = tracker.update([cluster(55, BLUE, RED), cluster(205, YELLOW), cluster(250, PINK)])
    assert labels_by_bearing(second) == {55: 3, 205: 2, 250: 4}
    assert [d.label for d in second] == [2, 3, 4]


def test_merge_needs_two_previous_directions_and_waypoints_within_tolerance() -> None:
    tracker = DirectionTracker(DirectionConfig(merge_tolerance=0.25))
    tracker.update([cluster(30, BLUE), cluster(80, RED)])
    moved = (RED[0] + 0.3, RED[1])  # farther than the tolerance: not the same location
    result = tracker.update([cluster(50, BLUE, moved)])
    assert [d.label for d in result] == [0]  # angular match to blue (20 deg) beats red (30 deg)
    tracker.reset()
    tracker.update([cluster(30, BLUE), cluster(80, RED)])
    close = (RED[0] + 0.2, RED[1])
    assert [d.label for d in tracker.update([cluster(50, BLUE, close)])] == [2]


def test_angular_association_is_greedy_by_increasing_distance() -> None:
    tracker = DirectionTracker(DirectionConfig())
    tracker.update([cluster(0, (1.0, 0.0)), cluster(60, (0.0, 1.0))])
    # New at 40 is 20 from label 1 (60) and 40 from label 0; new at 350 is 10 from label 0.
    result = tracker.update([cluster(40, (5.0, 5.0)), cluster(350, (6.0, 6.0))])
    assert labels_by_bearing(result) == {40: 1, 350: 0}


def test_unmatched_directions_are_dropped_and_far_jumps_get_fresh_labels() -> None:
    tracker = DirectionTracker(DirectionConfig())
    tracker.update([cluster(10, (1.0, 0.0)), cluster(100, (0.0, 1.0))])
    result = tracker.update([cluster(195, (-1.0, 0.0))])  # 95 deg from label 1: beyond the 90 deg gate
    assert [d.label for d in result] == [2]
    wide = DirectionTracker(DirectionConfig(association_gate_deg=180.0))
    wide.update([cluster(10, (1.0, 0.0)), cluster(100, (0.0, 1.0))])
    assert [d.label for d in wide.update([cluster(195, (-1.0, 0.0))])] == [1]


def test_waypoints_coincide() -> None:
    a = np.array([[0.0, 0.0], [5.0, 5.0]])
    assert waypoints_coincide(a, np.array([[5.1, 5.1]]), 0.25)
    assert not waypoints_coincide(a, np.array([[5.3, 5.0]]), 0.25)
    assert not waypoints_coincide(a, np.empty((0, 2)), 0.25)


@settings(max_examples=100, deadline=None)
@given(
    st.integers(1, 5),
    st.floats(0.0, 360.0),
    st.lists(st.lists(st.floats(-5.0, 5.0), min_size=5, max_size=5), min_size=1, max_size=6),
)
def test_labels_are_stable_under_bearing_jitter(count: int, offset: float, jitters: list[list[float]]) -> None:
    """Directions at least 72 degrees apart, re-observed with +-5 degrees of noise and fresh waypoints."""
    tracker = DirectionTracker(DirectionConfig())
    base = [offset + k * 360.0 / count for k in range(count)]
    first = tracker.update([cluster(b, (10.0 * k, 0.0)) for k, b in enumerate(base)])
    expected = [d.label for d in first]
    for step, noise in enumerate(jitters, start=1):
        clusters = [cluster(b + noise[k], (10.0 * k, 100.0 * step)) for k, b in enumerate(base)]
        result = tracker.update(clusters)
        assert sorted(d.label for d in result) == expected
        for k, b in enumerate(base):
            match = min(result, key=lambda d, b=b: abs(math.remainder(math.degrees(d.bearing) - b, 360.0)))
            assert match.label == first[k].label


waypoint_sets = st.lists(
    arrays(np.float64, st.tuples(st.integers(0, 4), st.just(2)), elements=st.sampled_from([0.0, 0.1, 0.25, 0.3, 1.0])),
    max_size=5,
)


@settings(max_examples=150, deadline=None)
@given(a=waypoint_sets, b=waypoint_sets, tolerance=st.sampled_from([0.1, 0.25, 0.3]))
def test_coinciding_of_all_pairs_is_waypoints_coincide_per_pair(
    a: list[np.ndarray], b: list[np.ndarray], tolerance: float
) -> None:
    """The tracker's one-operation pair test equals the per-pair test, boundaries included."""
    expected = [[waypoints_coincide(x, y, tolerance) for y in b] for x in a]
    assert coinciding(a, b, tolerance).tolist() == expected
