"""Property tests: invalid frames change nothing, random frames keep the maps' invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.frontiers import component_at
from drivenav.mapping.kernels import pocket_size, pocket_sizes, raster_components
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.synthetic import Box3, BoxWorld
from drivenav.types import CameraIntrinsics, Pose

K = CameraIntrinsics.from_hfov(32, 24, 79.0)
CONFIG = MappingConfig(initial_size=6.0, growth_margin=1.0, pixel_stride=1)
HOLES = st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, -1.0, -1e30])
CLIPS = st.sampled_from([0.5, 0.505, 5.0, 4.995, 7.0, 1e30])
poses = st.builds(
    Pose,
    st.floats(-20.0, 20.0),
    st.floats(-20.0, 20.0),
    st.floats(-4 * math.pi, 4 * math.pi),
)


def first_map(pose: Pose) -> OccupancyMapper:
    mapper = OccupancyMapper(CONFIG)
    world = BoxWorld((Box3((pose.x + 1.02, pose.x + 1.5), (pose.y - 5.0, pose.y + 5.0)),))
    mapper.update(world.render(Pose(pose.x, pose.y, 0.0), K), K, pose)
    return mapper


@settings(max_examples=40, deadline=None)
@given(pose=poses, frame=arrays(np.float32, (24, 32), elements=HOLES))
def test_frames_of_holes_change_nothing(pose: Pose, frame: np.ndarray) -> None:
    mapper = first_map(pose)
    before = mapper.snapshot()
    mapper.update(frame, K, pose)
    after = mapper.snapshot()
    assert after.grid == before.grid
    for layer in ("obstacle", "explored", "navigable"):
        np.testing.assert_array_equal(getattr(after, layer), getattr(before, layer))


@settings(max_examples=40, deadline=None)
@given(pose=poses, frame=arrays(np.float32, (24, 32), elements=CLIPS | HOLES))
def test_clip_values_never_add_obstacles(pose: Pose, frame: np.ndarray) -> None:
    mapper = OccupancyMapper(CONFIG)
    mapper.update(frame, K, pose)
    assert not mapper.snapshot().obstacle.any()


@settings(max_examples=40, deadline=None)
@given(
    steps=st.lists(
        st.tuples(poses, arrays(np.float32, (24, 32), elements=st.floats(0.25, 6.0, width=32) | HOLES)),
        min_size=1,
        max_size=3,
    )
)
def test_random_frames_keep_the_invariants(steps: list[tuple[Pose, np.ndarray]]) -> None:
    mapper = OccupancyMapper(CONFIG)
    for pose, frame in steps:
        mapper.update(frame, K, pose)
        assert mapper.last_update is not None and mapper.last_update.accepted
    snap = mapper.snapshot()
    assert not (snap.navigable & ~snap.explored).any()
    assert not (snap.navigable & snap.obstacle).any()
    obstacle_xy = snap.grid.cell_to_world(np.argwhere(snap.obstacle))
    near_any = np.zeros(len(obstacle_xy), dtype=np.bool_)
    for pose, _ in steps:
        near_any |= np.hypot(obstacle_xy[:, 0] - pose.x, obstacle_xy[:, 1] - pose.y) <= 5.0 * 1.3 + 0.05
    assert near_any.all()
    for f in mapper.frontiers():
        assert snap.navigable[f.cells[:, 0], f.cells[:, 1]].all()
        assert f.unexplored_area >= CONFIG.min_frontier_area


@settings(max_examples=80, deadline=None)
@given(
    mask=arrays(np.bool_, st.tuples(st.integers(1, 24), st.integers(1, 24))),
    eight=st.booleans(),
    data=st.data(),
)
def test_component_at_is_the_labelled_component(mask: NDArray[np.bool_], eight: bool, data: st.DataObject) -> None:
    """The flood fill behind ``component_at`` gives exactly scipy's connected-component label."""
    i = data.draw(st.integers(0, mask.shape[0] - 1))
    j = data.draw(st.integers(0, mask.shape[1] - 1))
    labels, _ = ndimage.label(mask, structure=ndimage.generate_binary_structure(2, 2 if eight else 1))
    expected = labels == labels[i, j] if mask[i, j] else np.zeros_like(mask)
    np.testing.assert_array_equal(component_at(mask, (i, j), eight=eight), expected)


@settings(max_examples=80, deadline=None)
@given(mask=arrays(np.bool_, st.tuples(st.integers(1, 24), st.integers(1, 24))))
def test_raster_components_group_like_scipy_label(mask: NDArray[np.bool_]) -> None:
    """Frontier grouping: scipy's 8-connected labels, components in label order, cells in raster order."""
    labels, count = ndimage.label(mask, structure=ndimage.generate_binary_structure(2, 2))
    cells, starts = raster_components(mask)
    assert len(starts) == count + 1
    for k in range(count):
        expected = np.argwhere(labels == k + 1)
        np.testing.assert_array_equal(cells[starts[k] : starts[k + 1]], expected)


@settings(max_examples=60, deadline=None)
@given(
    passable=arrays(np.bool_, st.tuples(st.integers(1, 30), st.integers(1, 30))),
    seed=st.integers(0, 2**31),
    margin=st.integers(0, 6),
)
def test_pocket_sizes_of_all_groups_equal_one_call_per_group(
    passable: NDArray[np.bool_], seed: int, margin: int
) -> None:
    rng = np.random.default_rng(seed)
    cells, starts = raster_components(rng.random(passable.shape) < 0.2)
    sizes = pocket_sizes(passable, cells, starts, margin)
    for k, size in enumerate(sizes):
        group = cells[starts[k] : starts[k + 1]]
        lo = np.maximum(group.min(axis=0) - margin, 0)
        hi = np.minimum(group.max(axis=0) + margin + 1, passable.shape)
        assert size == pocket_size(passable, group, np.array([lo[0], hi[0], lo[1], hi[1]]))


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-1e4, 1e4, allow_nan=False),
    y=st.floats(-1e4, 1e4, allow_nan=False),
    ox=st.floats(-100.0, 100.0),
    oy=st.floats(-100.0, 100.0),
    resolution=st.sampled_from([0.01, 0.025, 0.05, 0.1, 0.3]),
)
def test_cell_of_one_point_equals_the_array_conversion(
    x: float, y: float, ox: float, oy: float, resolution: float
) -> None:
    grid = GridSpec(resolution, (ox, oy), (10, 10))
    assert grid.cell_at(x, y) == tuple(int(v) for v in grid.world_to_cell((x, y)))


def _pocket_reference(passable: NDArray[np.bool_], cells: NDArray[np.int64], window: NDArray[np.int64]) -> int:
    """The pocket by scipy's 4-connected labels of the window: the components holding a seed, summed."""
    r0, r1, c0, c1 = (int(v) for v in window)
    labels, _ = ndimage.label(passable[r0:r1, c0:c1])
    seeds = (cells[:, None, :] + np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])[None]).reshape(-1, 2) - (r0, c0)
    inside = (seeds >= 0).all(axis=1) & (seeds < labels.shape).all(axis=1)
    touched = set(labels[seeds[inside, 0], seeds[inside, 1]].tolist()) - {0}
    return int(np.isin(labels, list(touched)).sum())


@settings(max_examples=80, deadline=None)
@given(
    passable=arrays(np.bool_, st.tuples(st.integers(1, 30), st.integers(1, 30))),
    seed=st.integers(0, 2**31),
    margin=st.integers(0, 6),
)
def test_pocket_sizes_are_scipys_labelled_components(passable: NDArray[np.bool_], seed: int, margin: int) -> None:
    """The scan-line fill behind the pockets counts exactly the 4-connected components it seeds."""
    rng = np.random.default_rng(seed)
    cells, starts = raster_components(rng.random(passable.shape) < 0.2)
    for k, size in enumerate(pocket_sizes(passable, cells, starts, margin)):
        group = cells[starts[k] : starts[k + 1]]
        lo = np.maximum(group.min(axis=0) - margin, 0)
        hi = np.minimum(group.max(axis=0) + margin + 1, passable.shape)
        assert size == _pocket_reference(passable, group, np.array([lo[0], hi[0], lo[1], hi[1]]))


@pytest.mark.parametrize("density", [0.45, 0.6, 0.8])
def test_fill_of_large_ragged_masks_is_the_labelled_component(density: float) -> None:
    """Large masks with thousands of short runs (they grow the scan-line fill's seed stack past its first size)."""
    rng = np.random.default_rng(int(density * 100))
    mask = rng.random((300, 260)) < density
    for eight in (False, True):
        labels, _ = ndimage.label(mask, structure=ndimage.generate_binary_structure(2, 2 if eight else 1))
        biggest = int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
        i, j = np.argwhere(labels == biggest)[0]
        np.testing.assert_array_equal(component_at(mask, (int(i), int(j)), eight=eight), labels == biggest)
