"""The incremental speed field against the from-scratch one: the same numbers, nearest features and
tie-breaks after every change, on random grids, on a growing house map and along an embedded episode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from drivenav.directions import bench
from drivenav.directions.edt import IncrementalTransform, feature_transform, squared_edt
from drivenav.directions.speed import SpeedField, SpeedFieldBuilder, build_speed_field
from drivenav.directions.synthetic import extract_frontiers, make_snapshot, rect
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import SpeedFieldConfig

FIELD_ARRAYS = ("traversable", "obstacle_sq", "skeleton", "skeleton_sq", "speed")


def _transform(feature: np.ndarray, features: bool) -> tuple[np.ndarray, ...]:
    return feature_transform(feature) if features else (squared_edt(feature),)


def _outputs(kept: IncrementalTransform, features: bool) -> tuple[np.ndarray, ...]:
    return (kept.sq, kept.frow, kept.fcol) if features else (kept.sq,)


@settings(max_examples=100, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.integers(1, 20),
    st.integers(1, 20),
    st.sampled_from([0.02, 0.1, 0.4]),
    st.booleans(),
    st.booleans(),
)
def test_incremental_transform_equals_a_fresh_one_after_every_change(
    seed: int, rows: int, cols: int, density: float, features: bool, grow_only: bool
) -> None:
    """Cells appear (and, unless ``grow_only``, disappear; sparse grids tie a lot); after each update the outputs are
    a fresh transform's, and the flagged rows are exactly those whose outputs changed. Growing grids exercise the
    patched rows (distances only fall), shrinking ones the redone rows."""
    rng = np.random.default_rng(seed)
    feature = rng.random((rows, cols)) < density
    kept = IncrementalTransform(feature, features)
    assert all(
        np.array_equal(a, b) for a, b in zip(_outputs(kept, features), _transform(feature, features), strict=True)
    )
    for _ in range(5):
        before = [a.copy() for a in _outputs(kept, features)]
        flips = rng.random((rows, cols)) < rng.choice([0.01, 0.05, 0.3])
        feature = feature | flips if grow_only else feature ^ flips
        changed = kept.update(feature)
        want = _transform(feature, features)
        for got, expected in zip(_outputs(kept, features), want, strict=True):
            np.testing.assert_array_equal(got, expected)
        differs = np.zeros(rows, np.bool_)
        for old, new in zip(before, want, strict=True):
            differs |= (old != new).any(axis=1)
        np.testing.assert_array_equal(changed, differs)


def _assert_same_field(got: SpeedField, want: SpeedField) -> None:
    assert got.window == want.window
    for name in FIELD_ARRAYS:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)


def _house_steps() -> list[tuple[MapSnapshot, list[Frontier]]]:
    """The bench house seen from its viewpoints one after another (the explored map grows, obstacles appear, the
    crop window grows past the builder's capacity window), then with a wall knocked through (obstacles vanish)."""
    free = bench.house_free_space()
    explored = np.zeros_like(free)
    steps = []
    for viewpoint in bench.VIEWPOINTS + bench.ROOM_VIEWPOINTS[:3]:
        explored |= bench.visible_cells(free, viewpoint)
        snapshot = make_snapshot(free, explored, bench.RESOLUTION, inflation=0.15)
        steps.append((snapshot, extract_frontiers(snapshot, bench.MIN_FRONTIER_CELLS)))
    rect(free, 6.5, 10.9, 9.0, 11.1)
    snapshot = make_snapshot(free, explored, bench.RESOLUTION, inflation=0.15)
    steps.append((snapshot, extract_frontiers(snapshot, bench.MIN_FRONTIER_CELLS)))
    return steps


def test_builder_gives_build_speed_field_at_every_step_of_a_growing_house_map() -> None:
    """Each field's speed and traversable cells are its own (later builds leave them alone); the distances and the
    skeleton are read-only views of the builder's arrays."""
    config = SpeedFieldConfig()
    builder = SpeedFieldBuilder(config)
    fields = []
    for snapshot, frontiers in _house_steps():
        field = builder.build(snapshot, frontiers)
        want = build_speed_field(snapshot, frontiers, config)
        _assert_same_field(field, want)
        assert not any(getattr(field, name).flags.writeable for name in ("obstacle_sq", "skeleton", "skeleton_sq"))
        fields.append((field, want))
    for field, want in fields:
        np.testing.assert_array_equal(field.speed, want.speed)
        np.testing.assert_array_equal(field.traversable, want.traversable)


def test_builder_keeps_its_arrays_while_the_map_stays_inside_them() -> None:
    """Exploring a little more inside the capacity window updates the kept arrays instead of starting over."""
    free = bench.house_free_space()
    explored = bench.visible_cells(free, bench.VIEWPOINTS[2])
    config = SpeedFieldConfig()
    builder = SpeedFieldBuilder(config)
    first = make_snapshot(free, explored, bench.RESOLUTION, inflation=0.15)
    builder.build(first, extract_frontiers(first))
    kept = builder._kept
    explored |= bench.visible_cells(free, (11.8, 11.0))
    second = make_snapshot(free, explored, bench.RESOLUTION, inflation=0.15)
    frontiers = extract_frontiers(second)
    _assert_same_field(builder.build(second, frontiers), build_speed_field(second, frontiers, config))
    assert builder._kept is kept


def test_builder_keeps_its_arrays_when_the_grid_grows() -> None:
    """The mapper grows its grid by whole cells around the map: the world cells, hence the kept arrays, stay."""
    snapshot, frontiers = _house_steps()[1]
    config = SpeedFieldConfig()
    builder = SpeedFieldBuilder(config)
    builder.build(snapshot, frontiers)
    kept = builder._kept
    pad = ((7, 3), (5, 11))
    grid = snapshot.grid
    grown = MapSnapshot(
        GridSpec(
            grid.resolution,
            (grid.origin[0] - 5 * grid.resolution, grid.origin[1] - 7 * grid.resolution),
            (grid.shape[0] + 10, grid.shape[1] + 16),
        ),
        *(np.pad(a, pad) for a in (snapshot.obstacle, snapshot.explored, snapshot.navigable)),
    )
    moved = [dataclasses.replace(f, cells=f.cells + np.array([7, 5])) for f in frontiers]
    _assert_same_field(builder.build(grown, moved), build_speed_field(grown, moved, config))
    assert builder._kept is kept


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from([0.05, 0.1]))
@example(seed=3, resolution=0.05)
def test_builder_gives_build_speed_field_on_random_growing_maps(seed: int, resolution: float) -> None:
    """A sparsely cluttered 64 x 64 room explored rectangle by rectangle; a grid change in the middle starts over."""
    rng = np.random.default_rng(seed)
    free = rng.random((64, 64)) > 0.01
    free[[0, -1], :] = False
    free[:, [0, -1]] = False
    explored = np.zeros_like(free)
    config = SpeedFieldConfig()
    builder = SpeedFieldBuilder(config)
    for step in range(10):
        r, c = rng.integers(0, 56, size=2)
        explored[r : r + rng.integers(4, 30), c : c + rng.integers(4, 30)] = True
        origin = (0.0, 0.0) if step < 7 else (1.0, 0.0)
        snapshot = make_snapshot(free, explored, resolution, origin, inflation=resolution)
        frontiers = extract_frontiers(snapshot)
        _assert_same_field(builder.build(snapshot, frontiers), build_speed_field(snapshot, frontiers, config))


def test_uniform_ablation_builds_the_uniform_field() -> None:
    snapshot, frontiers = _house_steps()[0]
    config = SpeedFieldConfig(weighted=False)
    _assert_same_field(
        SpeedFieldBuilder(config).build(snapshot, frontiers), build_speed_field(snapshot, frontiers, config)
    )


@pytest.mark.parametrize("agent", ["drive-nav"])
def test_every_step_of_an_embedded_episode_gets_the_from_scratch_field(
    agent: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The agent's pipeline, step by step through an embedded episode, against a recomputation from the map."""
    from drivenav.benchmarks.agent_bench import bench_agent

    builds: list[int] = []
    incremental = SpeedFieldBuilder.build

    def checked(self: SpeedFieldBuilder, snapshot: MapSnapshot, frontiers: list[Frontier]) -> SpeedField:
        field = incremental(self, snapshot, frontiers)
        _assert_same_field(field, build_speed_field(snapshot, frontiers, self._config))
        builds.append(1)
        return field

    monkeypatch.setattr(SpeedFieldBuilder, "build", checked)
    bench_agent(episodes=1, max_steps=80, agent_name=agent)
    assert len(builds) > 40
