"""Stairs read from depth (drivenav.mapping.stairs): a flight seen from its foot is found with its heading and
entry, a stairwell seen from its opening is a way down, walls neither; the plane search finds a flight's bearing
among what a run reaches beside it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.floor_scenes import FLIGHT, STOREY, two_floors

from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.stairs import (
    NO_POINT,
    Relief,
    StairCandidate,
    StairTuning,
    find_railings,
    find_stairs,
)
from drivenav.mapping.types import MapSnapshot
from drivenav.types import Action, Pose, SimConfig

SIM = SimConfig()
TUNING = StairTuning()


def scanned(start: tuple[float, float, float], yaw: float, turns: int) -> tuple[OccupancyMapper, Pose]:
    """A mapper with stair layers fed the frames of ``turns`` left turns from ``start`` in the two-storey building
    (episode frame: the start pose), and the start's world pose."""
    building = two_floors()
    env = EmbeddedEnv(lambda _: building, SIM)
    episode = Episode(
        episode_id="0",
        scene_id=building.scene_id,
        start_position=world_to_habitat(*start),
        start_rotation=yaw_to_quaternion(yaw),
        object_category="bed",
        goals=(),
    )
    observation = env.reset(episode)
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM), TUNING)
    for _ in range(turns + 1):
        mapper.update(observation.depth, observation.intrinsics, observation.pose, observation.pose.z)
        observation = env.step(Action.TURN_LEFT)
    return mapper, env.start_pose


def to_world(start: Pose, candidate: StairCandidate) -> tuple[float, float, float]:
    """The candidate's entry and heading in the world frame."""
    entry = start.compose(Pose(*candidate.entry, 0.0))
    return entry.x, entry.y, math.remainder(candidate.heading + start.yaw, 2.0 * math.pi)


@pytest.mark.parametrize("yaw", [0.0, 0.5])
def test_a_flight_seen_from_its_foot_is_a_way_up_along_its_heading(yaw: float) -> None:
    mapper, start = scanned((1.0, 2.5, 0.0), yaw, turns=2)
    relief = mapper.relief()
    assert relief is not None
    ways = find_stairs(relief, mapper.snapshot(), TUNING)
    assert len(ways) == 1 and ways[0].up
    x, y, heading = to_world(start, ways[0])
    assert abs(math.degrees(heading) - FLIGHT.heading) < 8.0  # the flight rises along +x
    assert FLIGHT.foot[0] - 0.8 < x < FLIGHT.foot[0] and abs(y - FLIGHT.foot[1]) < 0.35  # on the floor before it


def test_the_stairwell_seen_from_its_opening_is_a_way_down() -> None:
    mapper, start = scanned((7.0, 2.5, STOREY), math.pi, turns=0)  # upstairs, facing the flight's top
    relief = mapper.relief()
    assert relief is not None and relief.drops.any()
    ways = find_stairs(relief, mapper.snapshot(), TUNING)
    assert [w.up for w in ways] == [False]
    x, _, heading = to_world(start, ways[0])
    assert abs(math.degrees(math.remainder(heading - math.pi, 2.0 * math.pi))) < 30.0  # down runs toward -x
    assert 5.5 < x < 7.0  # at the opening, the flight's top (x = 6.05 m), on the floor before it


def test_walls_seen_from_across_a_floor_are_neither_stairs_nor_drops() -> None:
    mapper, _ = scanned((7.0, 2.5, 0.0), -math.pi / 2.0, turns=0)  # facing the south wall, the stairs behind
    relief = mapper.relief()
    assert relief is not None
    assert not relief.drops.any()
    assert find_stairs(relief, mapper.snapshot(), TUNING) == []
    seen = relief.top[np.isfinite(relief.top)]
    assert seen.max() < 0.05  # a wall's face is no upward-facing point: only the floor is in the relief


def synthetic(bearing_deg: float, with_railing: bool) -> tuple[Relief, GridSpec]:
    """A 6 x 6 m relief: free floor around (1, 3), a flight 1 m wide rising from x = 1.5 along ``bearing_deg`` (treads
    0.27 m deep, risers 0.18 m) and, with ``with_railing``, a railing's top 0.9 m above the treads along one side and
    a low box by the foot on the other, both reached by the run's climb."""
    grid = GridSpec(0.05, (0.0, 0.0), (120, 120))
    top = np.full(grid.shape, NO_POINT, np.float32)
    rows, cols = np.indices(grid.shape)
    xy = grid.cell_to_world(np.column_stack([rows.ravel(), cols.ravel()])).reshape(*grid.shape, 2)
    u = np.array([math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg))])
    rel = xy - np.array([1.5, 3.0])
    along, across = rel @ u, rel @ np.array([-u[1], u[0]])
    flight = (along >= 0.0) & (along < 2.4) & (np.abs(across) <= 0.5)
    top[flight] = 0.18 * (np.floor(along[flight] / 0.27) + 1.0)
    if with_railing:
        railing = (along >= 0.0) & (along < 2.4) & (across > 0.5) & (across < 0.6)
        top[railing] = 0.18 * (np.floor(along[railing] / 0.27) + 1.0) + 0.9
        box = (along >= 0.0) & (along < 0.6) & (across < -0.5) & (across > -1.0)
        top[box] = 0.3
    top[(along < 0.0) & (along > -1.0) & (np.abs(across) <= 1.0)] = 0.0
    return Relief(grid, top, np.zeros(grid.shape, bool)), grid


@pytest.mark.parametrize("bearing", [0.0, 37.0, 90.0, -120.0])
@pytest.mark.parametrize("with_railing", [False, True])
def test_the_plane_search_finds_the_flights_bearing(bearing: float, with_railing: bool) -> None:
    relief, grid = synthetic(bearing, with_railing)
    free = relief.top == 0.0
    snapshot = MapSnapshot(grid, np.zeros(grid.shape, bool), free, free)
    ways = find_stairs(relief, snapshot, TUNING)
    assert len(ways) == 1 and ways[0].up
    error = math.degrees(math.remainder(ways[0].heading - math.radians(bearing), 2.0 * math.pi))
    assert abs(error) <= 2.5  # the bearings tried are 2 degrees apart


def test_a_railing_seen_from_beside_suggests_looking_from_beyond_its_ends() -> None:
    """Upstairs beside the stairwell (its railing along y = 2 m between x = 2 and 6.05 m, 1.2 m away), turning a full
    circle, no floor is seen past the 0.9 m railing and no drop: no way down. The railing is a thin line about the
    camera's height with unseen floor behind it, and each of its ends gives a place to look from, 0.6 m beyond it and
    0.45 m toward the unseen side, looking back along the line: past the flight's top, where the stairs arrive,
    looking down them."""
    mapper, start = scanned((4.0, 0.8, STOREY), 0.0, turns=11)
    relief, snapshot = mapper.relief(), mapper.snapshot()
    assert relief is not None and not relief.drops.any()
    assert find_stairs(relief, snapshot, TUNING) == []
    suspects = sorted((to_world(start, s), s) for s in find_railings(relief, snapshot, TUNING))
    assert all(not s.up and not s.seen for _, s in suspects)
    ends = [world for world, _ in suspects]
    assert len(ends) == 2
    (x0, y0, h0), (x1, y1, h1) = ends
    assert abs(y0 - 2.45) < 0.15 and abs(y1 - 2.45) < 0.15  # toward the unseen side, the stairwell's middle
    assert x1 > 6.05 and abs(math.remainder(h1 - math.pi, 2.0 * math.pi)) < 0.2  # past the top, looking down the flight
    assert x0 < 2.4 and abs(math.remainder(h0, 2.0 * math.pi)) < 0.2  # the other end, looking the other way


def railing_map(top: float, rows: slice, cols: slice) -> tuple[Relief, MapSnapshot]:
    """A 5 x 5 m map seen up to y = 2 m, with obstacle cells of highest point ``top`` at ``rows, cols``."""
    grid = GridSpec(0.05, (0.0, 0.0), (100, 100))
    obstacle = np.zeros((100, 100), np.bool_)
    obstacle[rows, cols] = True
    explored = np.zeros((100, 100), np.bool_)
    explored[:40, :] = True
    heights = np.full((100, 100), NO_POINT, np.float32)
    heights[rows, cols] = top
    relief = Relief(grid, heights, np.zeros((100, 100), np.bool_))
    return relief, MapSnapshot(grid, obstacle, explored | obstacle, explored & ~obstacle)


@pytest.mark.parametrize(
    ("top", "rows", "cols", "found"),
    [
        (0.88, slice(40, 41), slice(20, 80), 2),  # a 3 m line at the camera's height, unseen floor behind: both ends
        (0.88, slice(40, 41), slice(20, 50), 0),  # 1.5 m: shorter than a flight's run
        (2.4, slice(40, 41), slice(20, 80), 0),  # a wall's height
        (0.88, slice(40, 52), slice(20, 80), 0),  # an area of that height: a furniture top seen, no line
    ],
)
def test_only_a_long_thin_line_about_the_cameras_height_suggests_a_way_down(
    top: float, rows: slice, cols: slice, found: int
) -> None:
    relief, snapshot = railing_map(top, rows, cols)
    assert len(find_railings(relief, snapshot, TUNING)) == found


def test_an_end_with_a_railing_across_it_is_not_looked_from_when_the_other_is_clear() -> None:
    """A 3 m railing along y = 2 m (x from 1 to 4 m) with a railing across its west end on the unseen side (x = 1 m,
    y from 2 to 3 m): the stairs cannot arrive there, so only the east end is looked from, looking back west."""
    relief, snapshot = railing_map(0.88, slice(40, 41), slice(20, 80))
    snapshot.obstacle[40:60, 19:20] = True
    suspects = find_railings(relief, snapshot, TUNING)
    assert len(suspects) == 1
    (x, y), heading = suspects[0].entry, suspects[0].heading
    assert x > 4.0 and 2.3 < y < 2.6 and abs(abs(heading) - math.pi) < 0.1
