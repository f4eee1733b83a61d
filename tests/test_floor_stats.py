"""``episodes stats`` on buildings of several storeys: a hand-built building measured storey by storey, the floor
change rule, generated episodes, and HM3D v1's multi-floor episodes read as they are.

The HM3D v1 fixture (``tests/data/hm3d-v1-floors``) is written by hand in HM3D's ObjectNav v1 layout: the split file
with HM3D's two category maps and no episodes, ``content/<scene>.json`` with the episodes (no goals; ``info`` with
``geodesic_distance``, ``euclidean_distance`` and ``closest_goal_object_id``, and no floor information) and
``goals_by_category`` (habitat-lab's ``ObjectGoal`` fields, view points with ``iou``), floats to 5 decimals. Its
scene is the two-storey home ``storeys/home_00000`` (HM3D's scans are not here), with positions from that home and
heights as HM3D's navmeshes give them, 0.16 m downstairs and 2.9 m upstairs. Its four episodes: from downstairs to the
beds (upstairs only), from upstairs to the beds, from upstairs to the sofa (downstairs only), and from downstairs to
the toilets (on both floors): two need a floor change. The files are plain JSON here and gzipped where a test puts
the split.
"""

from __future__ import annotations

import gzip
import json
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

import pytest

from agent_scenes import RES, Rect, carved_scene
from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.benchmarks.world_stats import (
    Share,
    StatsConfig,
    measure,
    measure_scene,
    needs_floor_change,
    storey_floors,
)
from drivenav.cli import main
from drivenav.envs.embedded.building import Building, Flight, Staircase, Storey, storeys_of
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import Room, Scene
from drivenav.envs.embedded.terrain import terrain_of
from drivenav.envs.habitat.benchmarks import BENCHMARKS, OBJECTNAV_V1
from drivenav.envs.habitat.layouts import read_split
from drivenav.episode import Episode, ObjectGoal, ViewPoint, world_to_habitat, yaw_to_quaternion
from drivenav.eval.episodes import load_episodes, save_episodes

HM3D_FLOORS = Path(__file__).parent / "data" / "hm3d-v1-floors"
SPLIT = "val"
CONFIG = StatsConfig()


def write_hm3d_floors(data_dir: Path) -> Path:
    """The HM3D v1 fixture gzipped where the ``hm3d-v1`` preset reads its ``val`` split under ``data_dir``; returns
    the split file."""
    split_file = data_dir / BENCHMARKS["hm3d-v1"].data_path.format(split=SPLIT)
    root = HM3D_FLOORS / SPLIT
    for path in sorted(root.rglob("*.json")):
        target = split_file.parent / f"{path.relative_to(root)}.gz"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(gzip.compress(path.read_bytes(), mtime=0))
    return split_file


# ------------------------------------------------------------------------------------- a building by hand


def labelled(scene_id: str, rooms: list[tuple[str, Rect]], doors: list[Rect]) -> Scene:
    """A 10 x 10 m plan: walls but for the rooms' rectangles (also their polygons) and the door gaps."""
    scene = carved_scene(scene_id, [rect for _, rect in rooms] + doors, size=10.0)
    scene.rooms = [Room(name, ((x0, y0), (x1, y0), (x1, y1), (x0, y1))) for name, (x0, y0, x1, y1) in rooms]
    return scene


HALL: Rect = (1.0, 1.0, 9.0, 3.0)


def ground() -> Scene:
    """A hallway along the south with a bedroom and a kitchen north of it, each with a door to it and one between
    them: one loop, round the T of wall (3 m across) between the three doors."""
    rooms = [("hallway", HALL), ("bedroom", (1.0, 3.2, 5.0, 6.0)), ("kitchen", (5.2, 3.2, 9.0, 6.0))]
    return labelled("test/storeyed", rooms, [(2.0, 3.0, 3.0, 3.2), (6.0, 3.0, 7.0, 3.2), (5.0, 4.0, 5.2, 5.0)])


def upper() -> Scene:
    """The same hallway and one bedroom through one door: a tree."""
    return labelled("test/storeyed", [("hallway", HALL), ("bedroom", (1.0, 3.2, 9.0, 6.0))], [(4.0, 3.0, 5.0, 3.2)])


def storeyed() -> Building:
    """Two storeys 3 m apart, joined by one straight flight along the hallway's south wall (16 risers of 0.1875 m,
    0.27 m treads, 1 m wide: x 2-6.05 m, y 1-2 m). Upstairs the stairwell meets that wall, so it encloses no
    island."""
    flight = Flight(foot=(2.0, 1.5), heading=0, width=1.0, risers=16, riser=0.1875, going=0.27, base=0.0)
    storeys = (Storey(ground(), 0.0), Storey(upper(), 3.0))
    return Building("test/storeyed", storeys, (Staircase(0, (flight,)),), source="test")


def test_a_building_is_measured_storey_by_storey() -> None:
    """Rooms, doors and loops of both floor plans together, each over its own floor (downstairs with the stairs,
    upstairs without the stairwell); the area both storeys' reachable cells (and the stairs'), for each agent."""
    building = storeyed()
    stats = measure_scene(building, CONFIG)
    assert (stats.storeys, stats.rooms, stats.corridors) == (2, 3, 2)
    assert stats.room_types == ("hallway", "bedroom", "kitchen", "hallway", "bedroom")
    assert stats.doors == (2, 2, 2, 1, 1)
    assert (stats.room_loops, stats.islands, stats.island_extent) == (1, 1, 1.0)
    downstairs = measure_scene(ground(), CONFIG)  # the ground floor alone: the building's first storey's figures
    assert (downstairs.rooms, downstairs.doors, downstairs.room_loops, downstairs.islands) == (2, (2, 2, 2), 1, 1)
    terrain = terrain_of(building, CONFIG.sim)
    (_, below), (_, above) = storey_floors(building, terrain)
    assert below[building.stair_cells[0]].all() and not above[building.holes[1]].any()  # the stairs, no stairwell
    reachable = terrain.reachable
    assert reachable[0].any() and reachable[1].any()  # both storeys, through the stairs
    assert stats.area_agent == pytest.approx(reachable.sum() * RES**2)
    hm3d = replace(CONFIG.sim, agent_radius=CONFIG.hm3d_radius, agent_height=CONFIG.hm3d_height)
    assert stats.area_hm3d == pytest.approx(terrain_of(building, hm3d).reachable.sum() * RES**2)
    assert stats.area_hm3d > stats.area_agent


# ------------------------------------------------------------------------------------ the floor change rule


def episode(start: float, views: list[float], info: dict[str, object] | None = None) -> Episode:
    """An episode starting at height ``start`` whose one goal has view points at ``views`` heights."""
    q = yaw_to_quaternion(0.0)
    points = tuple(ViewPoint(world_to_habitat(1.0, 1.0, h), q) for h in views)
    goal = ObjectGoal(1, "bed", world_to_habitat(1.0, 1.0, views[0]), points)
    return Episode("0", "storeys/home_00000", world_to_habitat(2.0, 2.0, start), q, "bed", (goal,), info or {})


@pytest.mark.parametrize(
    ("start", "views", "info", "change"),
    [
        (0.16, [2.9], None, True),  # HM3D: the goals one floor up
        (2.9, [0.16, 3.1], None, False),  # one view point on the start's floor is enough
        (0.0, [1.2], None, False),  # within half a storey (1.2 m)
        (0.0, [-1.21, 1.21], None, True),  # beyond it, above and below
        (0.0, [3.0], {"cross_floor": False}, False),  # the file's own floor information wins
        (0.0, [0.0], {"cross_floor": True}, True),
        (0.0, [3.0], {"cross_floor": "no"}, True),  # not true / false: decided from heights
    ],
)
def test_the_floor_change_rule(start: float, views: list[float], info: dict[str, object] | None, change: bool) -> None:
    assert needs_floor_change(episode(start, views, info), CONFIG.half_storey) is change


# --------------------------------------------------------------------------------------- generated episodes


def test_generated_storeys_episodes() -> None:
    """The shares follow the scenes' storeys and the episodes' ``info.cross_floor``; the height rule gives the same
    answer as ``info`` on every episode; distances run through the stairs (every ratio measured)."""
    library = SceneLibrary("storeys:3", 0)
    episodes = generate_episodes(library, 12, 5, storeys=Storeys(0.5))
    stats = measure(episodes, library, CONFIG)
    (scenes,), (figures,) = stats.scene_sets, stats.episode_sets
    storeys = {scene_id: len(storeys_of(library.load(scene_id))) for scene_id in library.scene_ids}
    counts = Counter(storeys.values())
    assert len(counts) > 1  # homes of one storey and of several
    assert scenes.storeys_per_scene == {str(n): Share(counts[n], 3) for n in sorted(counts)}
    several = sum(storeys[e.scene_id] > 1 for e in episodes)
    cross = [e.info.get("cross_floor") is True for e in episodes]
    assert (figures.in_multi_storey_scenes.count, figures.floor_change.count) == (several, sum(cross))
    assert 0 < sum(cross) < several  # both kinds among the episodes of multi-storey homes
    without = [replace(e, info={k: v for k, v in e.info.items() if k != "cross_floor"}) for e in episodes]
    assert [needs_floor_change(e, CONFIG.half_storey) for e in without] == cross
    assert figures.ratio is not None and figures.ratio.count == 12


# --------------------------------------------------------------------------------- HM3D v1's multi-floor files


@pytest.fixture
def hm3d_split(tmp_path: Path) -> Path:
    return write_hm3d_floors(tmp_path / "data")


def test_hm3d_v1_floors_read_as_they_are(hm3d_split: Path, tmp_path: Path) -> None:
    """Starts and view points keep their heights, through the split and through drivenav's own episodes file."""
    episodes = read_split(hm3d_split, OBJECTNAV_V1)
    assert [(e.object_category, e.start_height) for e in episodes] == [
        ("bed", 0.16),
        ("bed", 2.9),
        ("sofa", 2.9),
        ("toilet", 0.16),
    ]
    heights = {e.object_category: sorted({vp.height for g in e.goals for vp in g.view_points}) for e in episodes}
    assert heights == {"bed": [2.9], "sofa": [0.16], "toilet": [0.16, 2.9]}
    assert [g.position[1] for g in episodes[0].goals] == [3.18346, 3.24388]  # the beds' centres, upstairs
    assert episodes[0].info == {
        "geodesic_distance": 20.17684,
        "euclidean_distance": 6.78013,
        "closest_goal_object_id": 67,
    }
    saved = tmp_path / "episodes.json.gz"
    save_episodes(episodes, saved)
    assert load_episodes(saved) == episodes


def test_stats_on_hm3d_v1_floors(hm3d_split: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--format`` reads the split; two of its four episodes need a floor change by the height rule."""
    args = ["episodes", "stats", str(hm3d_split), "--format", OBJECTNAV_V1, "--scenes", "storeys:1", "--no-check"]
    assert main([*args, "--json"]) == 0
    captured = capsys.readouterr()
    assert "not checked against the scenes (--no-check)" in captured.err
    data = json.loads(captured.out)
    [scenes], [figures] = data["scene_sets"], data["episode_sets"]
    assert scenes["storeys_per_scene"] == {"2": {"count": 1, "total": 1, "share": 1.0}}
    assert figures["in_multi_storey_scenes"] == {"count": 4, "total": 4, "share": 1.0}
    assert figures["floor_change"] == {"count": 2, "total": 4, "share": 0.5}
    assert data["config"]["half_storey"] == 1.2
    assert math.isclose(figures["geodesic"]["mean"], (20.17684 + 9.5621 + 14.80461 + 13.53939) / 4)
    assert main(args) == 0
    table = capsys.readouterr().out
    assert "| storeys per scene | 2: 100.0 % (1 / 1) |" in table
    assert "| episodes in scenes of several storeys | 100.0 % (4 / 4) |" in table
    assert "of the start's height) | 50.0 % (2 / 4) |" in table


def test_a_missing_split_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "val" / "val.json.gz"
    assert main(["episodes", "stats", str(missing), "--format", OBJECTNAV_V1]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(missing) in err and "split file" in err
