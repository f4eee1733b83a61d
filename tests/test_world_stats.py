"""World and episode statistics (``drivenav episodes stats``) on hand-built scenes whose doors, loops, areas and
distance ratios are known by hand, plus the command end to end."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from agent_scenes import RES, Rect, carved_scene
from conftest import run_cli
from drivenav.benchmarks.floor_topology import enclosed_islands, room_graph, wall_free_floor
from drivenav.benchmarks.generate import generate_episodes
from drivenav.benchmarks.world_stats import Histogram, StatsConfig, measure_scene, scene_set, terrain_distances
from drivenav.envs.embedded.geodesic import largest_component
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import Room, Scene
from drivenav.envs.embedded.terrain import terrain_of
from drivenav.episode import Episode, ObjectGoal, ViewPoint, world_to_habitat, yaw_to_quaternion
from drivenav.eval.episodes import save_episodes
from drivenav.types import SimConfig

SIM = SimConfig()


def rooms_scene(
    scene_id: str, rooms: Sequence[tuple[str, Rect]], doors: Sequence[Rect] = (), size: float = 10.0
) -> Scene:
    """Walls everywhere but the rooms' rectangles (also their polygons) and the door gaps carved between them."""
    scene = carved_scene(scene_id, [rect for _, rect in rooms] + list(doors), size=size)
    scene.rooms = [Room(name, ((x0, y0), (x1, y0), (x1, y1), (x0, y1))) for name, (x0, y0, x1, y1) in rooms]
    return scene


def graph_of(scene: Scene) -> tuple[tuple[int, ...], int, int]:
    """Doors per room, room-graph loops and enclosed islands >= 1 m."""
    floor = wall_free_floor(scene, largest_component(scene.navigable_grid(SIM.agent_radius, SIM.agent_height)))
    graph = room_graph(scene, floor)
    return graph.degrees, graph.loops, enclosed_islands(floor, RES, 1.0)


def corridor_with_three_rooms() -> Scene:
    """A 9 x 1.5 m hallway with three rooms north of it, each through a 1 m door in a 0.2 m wall: a tree."""
    rooms = [
        ("hallway", (1.0, 1.0, 10.0, 2.5)),
        ("bedroom", (1.0, 2.7, 4.0, 6.0)),
        ("bathroom", (4.2, 2.7, 7.0, 6.0)),
        ("kitchen", (7.2, 2.7, 10.0, 6.0)),
    ]
    doors = [(2.0, 2.5, 3.0, 2.7), (5.0, 2.5, 6.0, 2.7), (8.0, 2.5, 9.0, 2.7)]
    return rooms_scene("test/corridor", rooms, doors, size=11.0)


def four_room_ring() -> Scene:
    """Four rooms in a 2 x 2 block, each with a door to its two neighbours: one loop around the central walls."""
    rooms = [
        ("living room", (1.0, 1.0, 4.0, 4.0)),
        ("dining room", (4.2, 1.0, 8.0, 4.0)),
        ("kitchen", (1.0, 4.2, 4.0, 8.0)),
        ("hallway", (4.2, 4.2, 8.0, 8.0)),
    ]
    doors = [(4.0, 2.0, 4.2, 3.0), (4.0, 6.0, 4.2, 7.0), (2.0, 4.0, 3.0, 4.2), (6.0, 4.0, 7.0, 4.2)]
    return rooms_scene("test/ring", rooms, doors)


def test_corridor_with_three_rooms_is_a_tree() -> None:
    degrees, loops, islands = graph_of(corridor_with_three_rooms())
    assert degrees == (3, 1, 1, 1)
    assert (loops, islands) == (0, 0)


def test_four_room_ring_has_one_loop() -> None:
    degrees, loops, islands = graph_of(four_room_ring())
    assert degrees == (2, 2, 2, 2)
    assert (loops, islands) == (1, 1)  # the plus-shaped wall between the four doors, 3 m across


def test_open_plan_joint_and_two_doors() -> None:
    """Living and dining share an open joint (no wall); the kitchen has a door to each: a triangle, one loop.
    A second door between the same two rooms is a second door and closes a loop of its own."""
    rooms = [
        ("living room", (1.0, 1.0, 4.0, 4.0)),
        ("dining room", (4.0, 1.0, 7.0, 4.0)),
        ("kitchen", (1.0, 4.2, 7.0, 7.0)),
    ]
    doors = [(2.0, 4.0, 3.0, 4.2), (5.0, 4.0, 6.0, 4.2)]
    assert graph_of(rooms_scene("test/open", rooms, doors)) == ((2, 2, 2), 1, 1)
    two = rooms_scene("test/two_doors", [("living room", (1.0, 1.0, 7.0, 4.0)), rooms[2]], doors)
    assert graph_of(two) == ((2, 2), 1, 1)


def test_door_gap_joining_three_rooms_is_one_connection() -> None:
    """A door gap (outside every polygon) that touches three rooms gives each one door and makes no loop."""
    rooms = [("bedroom", (1.0, 1.0, 4.0, 4.0)), ("bathroom", (4.6, 1.0, 8.0, 4.0)), ("hallway", (1.0, 4.6, 8.0, 7.0))]
    gap = [(3.5, 4.0, 5.0, 4.6), (4.0, 3.5, 4.6, 4.6)]  # an L of free cells at the corner of the three
    assert graph_of(rooms_scene("test/hub", rooms, gap)) == ((1, 1, 1), 0, 0)


def test_areas_counted_by_hand() -> None:
    """A closed 4 x 3 m room (80 x 60 cells): HM3D's 0.1 m agent loses 2 cells along each wall, drivenav's 0.18 m
    agent 4 (a cell counts if its centre is farther than the radius from every wall face)."""
    scene = rooms_scene("test/box", [("bedroom", (1.0, 1.0, 5.0, 4.0))])
    stats = measure_scene(scene, StatsConfig())
    assert stats.area_hm3d == pytest.approx(76 * 56 * RES**2)
    assert stats.area_agent == pytest.approx(72 * 52 * RES**2)
    assert (stats.rooms, stats.corridors, stats.doors, stats.room_loops) == (1, 0, (0,), 0)


def test_scene_figures_of_the_ring() -> None:
    stats = measure_scene(four_room_ring())
    assert (stats.rooms, stats.corridors, stats.room_loops, stats.islands) == (3, 1, 1, 1)
    assert stats.room_types == ("living room", "dining room", "kitchen", "hallway")
    assert len(stats.region_degrees) == 4 and all(d == 2 for d in stats.region_degrees)


def test_plan_islands_need_the_plan_extent() -> None:
    """A square ring corridor around a 4 m block, with a 0.5 m pillar in it: the block is a loop at 3 m; the
    pillar counts only at a smaller extent."""
    free = [(1.0, 1.0, 7.0, 2.0), (1.0, 6.0, 7.0, 7.0), (1.0, 1.0, 2.0, 7.0), (6.0, 1.0, 7.0, 7.0)]
    scene = carved_scene("ring_plan", free, size=8.0)
    scene.structure[round(1.25 / RES) : round(1.75 / RES), round(3.0 / RES) : round(3.5 / RES)] = 1
    stats = measure_scene(scene)
    assert (stats.rooms, stats.islands, stats.island_extent) == (None, 1, 3.0)
    floor = scene.structure == 0
    assert enclosed_islands(floor, RES, 0.4) == 2
    assert enclosed_islands(floor, RES, 4.5) == 0


def _episode(
    scene_id: str, start: tuple[float, float], points: Sequence[tuple[float, float]], geodesic: float
) -> Episode:
    q = yaw_to_quaternion(0.0)
    views = tuple(ViewPoint(world_to_habitat(*p), q) for p in points)
    goal = ObjectGoal(1, "plant", world_to_habitat(*points[0]), views)
    info = {"geodesic_distance": geodesic} if math.isfinite(geodesic) else {}
    return Episode("0", scene_id, world_to_habitat(*start), q, "plant", (goal,), info)


def test_ratio_uses_the_geodesically_nearest_view_point() -> None:
    """A U-shaped corridor: from (1, 1) the view point (1, 5) is 4 m away in a line but about 13 m round the U;
    (6, 1) is 5 m along the corridor. The ratio divides by the line to (6, 1): 5 / 5, not 5 / 4."""
    free = [(0.5, 0.5, 6.5, 1.5), (5.5, 0.5, 6.5, 5.5), (0.5, 4.5, 6.5, 5.5)]
    scene = carved_scene("u_turn", free, size=7.0)
    terrain = terrain_of(scene, SIM)
    assert terrain_distances(_episode("u_turn", (1.0, 1.0), [(1.0, 5.0), (6.0, 1.0)], 5.0), terrain) == (
        5.0,
        pytest.approx(1.0),
    )
    geodesic, ratio = terrain_distances(_episode("u_turn", (1.0, 1.0), [(1.0, 5.0)], math.nan), terrain)
    assert 12.0 < geodesic < 14.0  # measured when the file has none: about 12.8 m hugging the inner corners
    assert ratio == pytest.approx(geodesic / 4.0)


def test_scene_sets_by_id() -> None:
    assert [scene_set(s) for s in ("procedural/house_00001", "homes/home_00003", "uos_avz")] == [
        "procedural",
        "homes",
        "floor plans",
    ]


@given(st.lists(st.floats(min_value=-5.0, max_value=50.0, allow_nan=False), max_size=40))
def test_histogram_puts_each_value_in_its_bin(values: list[float]) -> None:
    edges = (0.0, 2.5, 10.0, 30.0, math.inf)
    histogram = Histogram.of(values, edges)
    assert sum(histogram.counts) == sum(v >= 0.0 for v in values)
    for k, count in enumerate(histogram.counts):
        assert count == sum(edges[k] <= v < edges[k + 1] for v in values)


def test_command_end_to_end(tmp_path: Path) -> None:
    path = tmp_path / "eps.json.gz"
    episodes = generate_episodes(SceneLibrary("procedural:2", 0), 4, 0)
    save_episodes(episodes, path)
    result = run_cli("episodes", "stats", str(path), "--scenes", "procedural", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == {"config", "scene_sets", "episode_sets", "scenes"}
    [scenes] = data["scene_sets"]
    assert scenes["name"] == "procedural" and scenes["scenes"] == len({e.scene_id for e in episodes})
    assert {"doors_per_room", "doors_by_type", "room_graph_loops", "island_loops", "area_hm3d"} <= set(scenes)
    [ep] = data["episode_sets"]
    assert ep["episodes"] == 4
    assert ep["geodesic"]["mean"] == pytest.approx(np.mean([e.geodesic_distance for e in episodes]))
    assert sum(ep["geodesic_histogram"]["counts"]) == 4
    assert ep["geodesic_histogram"]["edges"][-1] is None  # the open last bin, infinity as JSON null
    assert set(ep["ratio_below"]) == {"1.05", "1.2"}
    text = run_cli("episodes", "stats", str(path), "--scenes", "procedural")
    assert text.returncode == 0 and "| doors per room (corridors not counted) |" in text.stdout


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (("no_such_file.json.gz",), ("EPISODES", "no_such_file.json.gz", "benchmark name")),
        (("v1", "--scenes", "procedural"), ("episodes[", "scene_id", "--scenes procedural")),
    ],
)
def test_bad_input_is_one_line(args: tuple[str, ...], needles: tuple[str, ...]) -> None:
    result = run_cli("episodes", "stats", *args)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr
    for needle in needles:
        assert needle in lines[0]
