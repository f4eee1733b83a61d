"""VLFM's value map (:mod:`drivenav.mapping.value_map`): the FOV cone, its confidence and the confidence-weighted
fusion against hand-computed numbers, the value at a frontier point, and fusion's bounds as a property.

The camera of these tests has a 90 deg horizontal FOV (fx = 320 for 640 columns), so the half-FOV is 45 deg and the
confidence at angle ``a`` off the axis is ``0.25 + 0.75 cos^2(2a)``; it stands at the centre of cell (160, 160)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.grid import GridSpec
from drivenav.mapping.value_map import UNSEEN_VALUE, ValueMap, ValueMapConfig
from drivenav.types import CameraIntrinsics, Pose

CAMERA = CameraIntrinsics.from_hfov(640, 480, 90.0)
GRID = GridSpec(0.05, (-8.0, -8.0), (320, 320))
HERE = (0.025, 0.025)  # the centre of cell (160, 160)
ROW, COL = 160, 160


def _depth(value: float = 5.0) -> np.ndarray:
    return np.full((CAMERA.height, CAMERA.width), value, dtype=np.float32)


def _map(config: ValueMapConfig | None = None) -> ValueMap:
    return ValueMap(GRID, 5.0, config)


def _seen(value_map: ValueMap, di: int, dj: int) -> bool:
    return bool(value_map.confidence[ROW + di, COL + dj] > 0.0)


def test_a_cone_at_a_known_pose_on_an_empty_map() -> None:
    value_map = _map()
    value_map.update(0.8, Pose(*HERE, 0.0), _depth(), CAMERA)
    # 2 m straight ahead: on the optical axis
    assert value_map.value[ROW, COL + 40] == pytest.approx(0.8)
    assert value_map.confidence[ROW, COL + 40] == pytest.approx(1.0)
    # atan(1/2) off the axis: cos(2 atan(1/2)) = 0.6, so 0.25 + 0.75 * 0.36
    assert value_map.confidence[ROW + 20, COL + 40] == pytest.approx(0.52)
    assert value_map.confidence[ROW - 20, COL + 40] == pytest.approx(0.52)
    # just inside the FOV's edge: the minimum confidence
    assert value_map.confidence[ROW + 39, COL + 40] == pytest.approx(0.25, abs=1e-3)
    assert value_map.value[ROW + 39, COL + 40] == pytest.approx(0.8)
    # the frustum's far corner (4.95 m ahead, 5.8 m away) is seen, 5.05 m ahead is not, nor is anything behind,
    # outside the FOV or the camera's own cell
    assert _seen(value_map, 60, 99) and _seen(value_map, 0, 99) and not _seen(value_map, 0, 101)
    for di, dj in ((0, -40), (50, 40), (-50, 40), (0, 0), (10, -1)):
        assert not _seen(value_map, di, dj), (di, dj)
    assert value_map.value[value_map.confidence == 0.0].max() == 0.0


def test_the_confidence_falls_to_zero_at_the_edge_without_a_floor() -> None:
    value_map = _map(ValueMapConfig(min_confidence=0.0))
    value_map.update(1.0, Pose(*HERE, 0.0), _depth(), CAMERA)
    assert value_map.confidence[ROW, COL + 40] == pytest.approx(1.0)
    assert value_map.confidence[ROW + 20, COL + 40] == pytest.approx(0.36)
    assert 0.0 < value_map.confidence[ROW + 39, COL + 40] < 1e-3


def test_the_cone_turns_with_the_camera() -> None:
    value_map = _map()
    value_map.update(0.5, Pose(*HERE, math.pi / 2), _depth(), CAMERA)
    assert value_map.confidence[ROW + 40, COL] == pytest.approx(1.0)  # +y is ahead
    assert value_map.confidence[ROW + 40, COL + 20] == pytest.approx(0.52)
    assert not _seen(value_map, 0, 40) and not _seen(value_map, -40, 0)


def test_each_image_column_clips_the_cone_at_its_largest_depth() -> None:
    depth = _depth(5.0)
    depth[:, : CAMERA.width // 2] = 1.0  # the left half of the image (+y at yaw 0) sees a wall 1 m ahead
    depth[:100, 390:410] = 3.0  # a column's largest depth counts, not its first row's
    depth[100:, 390:410] = 0.5
    value_map = _map()
    value_map.update(0.3, Pose(*HERE, 0.0), depth, CAMERA)
    assert _seen(value_map, 10, 19) and not _seen(value_map, 10, 30)  # left: 0.95 m ahead seen, 1.5 m not
    assert _seen(value_map, -10, 30) and _seen(value_map, -10, 90)  # right: open to 5 m
    assert _seen(value_map, -15, 59) and not _seen(value_map, -15, 61)  # columns 390-410: open to 3 m


def test_depth_holes_see_nothing_in_their_columns() -> None:
    depth = _depth(5.0)
    depth[:, : CAMERA.width // 2] = np.nan
    depth[:, CAMERA.width // 2 :] = np.where(np.arange(CAMERA.height)[:, None] % 2 == 0, np.inf, 4.0)
    value_map = _map()
    value_map.update(0.3, Pose(*HERE, 0.0), depth, CAMERA)
    assert not _seen(value_map, 10, 30)  # left: all holes
    assert _seen(value_map, -10, 70) and not _seen(value_map, -10, 90)  # right: inf skipped, 4 m kept


def test_two_overlapping_frames_fuse_by_confidence() -> None:
    value_map = _map()
    value_map.update(0.8, Pose(*HERE, 0.0), _depth(), CAMERA)
    value_map.update(0.2, Pose(*HERE, math.atan2(20, 40)), _depth(), CAMERA)
    # cell A, on the first frame's axis (c = 1), 0.52 in the second: v = (1 * 0.8 + 0.52 * 0.2) / 1.52,
    # c = (1 + 0.52^2) / 1.52; cell B the other way round
    assert value_map.value[ROW, COL + 40] == pytest.approx(0.904 / 1.52)
    assert value_map.value[ROW + 20, COL + 40] == pytest.approx(0.616 / 1.52)
    for cell in ((ROW, COL + 40), (ROW + 20, COL + 40)):
        assert value_map.confidence[cell] == pytest.approx(1.2704 / 1.52)


def test_weak_new_data_does_not_overwrite_confident_data() -> None:
    """A new confidence below 0.35 and below the cell's leaves the cell as it was (VLFM's decision threshold)."""
    value_map = _map()
    value_map.update(0.8, Pose(*HERE, 0.0), _depth(), CAMERA)
    value_map.update(0.0, Pose(*HERE, math.atan2(39, 40)), _depth(), CAMERA)  # cell A at the second FOV's edge
    assert value_map.value[ROW, COL + 40] == pytest.approx(0.8)
    assert value_map.confidence[ROW, COL + 40] == pytest.approx(1.0)
    # cell (199, 200), at the first frame's edge (c ~ 0.25), is on the second one's axis
    assert value_map.value[ROW + 39, COL + 40] == pytest.approx(0.8 * 0.25 / 1.25, abs=1e-3)


def test_bad_frames_change_nothing() -> None:
    value_map = _map()
    value_map.update(float("nan"), Pose(*HERE, 0.0), _depth(), CAMERA)
    value_map.update(0.5, Pose(float("inf"), 0.0, 0.0), _depth(), CAMERA)
    value_map.update(0.5, Pose(*HERE, 0.0), np.full((10, 10), 5.0, dtype=np.float32), CAMERA)
    assert not value_map.confidence.any()


def test_value_at_is_the_median_of_the_seen_cells_near_a_point() -> None:
    value_map = _map()
    for (di, dj), value in zip(((0, 0), (3, 4), (-6, 8), (0, 11)), (0.1, 0.9, 0.5, 5.0), strict=True):
        value_map.value[ROW + di, COL + dj] = value
        value_map.confidence[ROW + di, COL + dj] = 0.5
    value_map.value[ROW + 1, COL + 1] = 7.0  # a value on an unseen cell does not count
    points = [HERE, (10.0, 10.0), (-2.0, 0.0), (-7.99, -7.99)]
    # radius 0.5 m = 10 cells: (0, 11) is outside, so the median of 0.1, 0.9, 0.5
    assert value_map.value_at(points).tolist() == [pytest.approx(0.5), UNSEEN_VALUE, UNSEEN_VALUE, UNSEEN_VALUE]
    assert value_map.value_at(np.empty((0, 2))).shape == (0,)


def test_the_map_keeps_its_values_in_place_when_the_grid_grows() -> None:
    value_map = _map()
    value_map.update(0.7, Pose(*HERE, 0.0), _depth(), CAMERA)
    point = (2.025, 0.025)
    before = value_map.value_at([point])
    grown = GridSpec(0.05, (-10.0, -9.0), (400, 380))
    value_map.follow(grown)
    assert value_map.grid == grown and value_map.value.shape == (400, 380)
    assert value_map.value_at([point]).tolist() == before.tolist()
    assert np.count_nonzero(value_map.confidence) > 0
    row, col = grown.cell_at(*point)
    assert value_map.confidence[row, col] == pytest.approx(1.0)


FRAMES = st.lists(
    st.tuples(st.floats(-1.0, 1.0), st.floats(-math.pi, math.pi), st.floats(0.3, 2.0)), min_size=1, max_size=6
)


@settings(max_examples=40, deadline=None)
@given(FRAMES)
def test_fused_values_stay_between_the_scores_and_confidences_in_range(
    frames: list[tuple[float, float, float]],
) -> None:
    camera = CameraIntrinsics.from_hfov(32, 24, 79.0)
    value_map = ValueMap(GridSpec(0.1, (-3.0, -3.0), (60, 60)), 2.0)
    for score, yaw, depth in frames:
        value_map.update(score, Pose(0.05, 0.05, yaw), np.full((24, 32), depth, dtype=np.float32), camera)
    seen = value_map.confidence > 0.0
    scores = [score for score, _, _ in frames]
    assert seen.any()
    assert (value_map.value[seen] >= min(scores) - 1e-9).all() and (value_map.value[seen] <= max(scores) + 1e-9).all()
    assert (value_map.confidence[seen] >= 0.25 - 1e-9).all() and (value_map.confidence[seen] <= 1.0 + 1e-9).all()
