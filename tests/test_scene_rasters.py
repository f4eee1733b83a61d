"""Scene rasters computed block by block equal the same tests run on every cell of the grid."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.grid import GridSpec

GRID = GridSpec(0.05, (-1.3, 0.7), (90, 120))
xs = st.floats(-2.0, 5.5)
ys = st.floats(0.0, 6.0)
objects = st.builds(
    ObjectInstance,
    st.integers(1, 1000),
    st.just("box"),
    st.tuples(xs, ys),
    st.tuples(st.floats(0.05, 2.0), st.floats(0.05, 2.0), st.floats(0.3, 1.5)),
    st.floats(-math.pi, math.pi),
)
corners = st.tuples(st.integers(-200, 550).map(lambda v: v / 100.0), st.integers(0, 600).map(lambda v: v / 100.0))
rooms = st.builds(Room, st.just("room"), st.lists(corners, min_size=3, max_size=7).map(tuple))


def _scene(objs: list[ObjectInstance], polygons: list[Room]) -> Scene:
    structure = np.full(GRID.shape, Material.FREE, dtype=np.uint8)
    structure[:, :3] = Material.WALL
    return Scene("test", GRID, structure, objs, polygons)


@settings(max_examples=60, deadline=None)
@given(st.lists(objects, max_size=6))
def test_obstacle_grid_equals_every_footprint_tested_on_every_cell(objs: list[ObjectInstance]) -> None:
    scene = _scene(objs, [])
    gx, gy = GRID.cell_centers()
    expected = scene.structure != Material.FREE
    for obj in scene.blocking_objects(0.88):
        expected |= obj.contains(gx, gy, margin=GRID.resolution / 2.0)
    np.testing.assert_array_equal(scene.obstacle_grid(0.88), expected)


@settings(max_examples=60, deadline=None)
@given(st.lists(rooms, max_size=4))
def test_room_index_equals_every_polygon_tested_on_every_cell(polygons: list[Room]) -> None:
    gx, gy = GRID.cell_centers()
    expected = np.zeros(GRID.shape, dtype=np.int16)
    for k, room in enumerate(polygons):
        expected[(expected == 0) & room.contains(gx, gy)] = k + 1
    np.testing.assert_array_equal(_scene([], polygons).room_index, expected)


def test_a_block_of_cell_centres_holds_the_whole_grids_values() -> None:
    gx, gy = GRID.cell_centers()
    block = GRID.block_covering([(0.2, 1.1), (1.7, 2.05)], margin=0.1)
    bx, by = GRID.cell_centers(*block)
    np.testing.assert_array_equal(bx, gx[block])
    np.testing.assert_array_equal(by, gy[block])
    inside = (gx >= 0.1) & (gx <= 1.8) & (gy >= 1.0) & (gy <= 2.15)
    assert inside[block].sum() == inside.sum() > 0
    assert GRID.block_covering(np.empty((0, 2))) == (slice(0, 0), slice(0, 0))
