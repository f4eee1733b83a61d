"""Pictures of an episode in a building: a top-down map per storey with the path split between them, egocentric
views from the floor the agent was on, coverage per floor, the floors on the report's episode page; and one-floor
pictures as they were."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.envs.embedded.building import Building, Storey
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Scene
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.eval.trace import EpisodeTrace
from drivenav.report.config import PictureChoice, ReportConfig
from drivenav.report.episode_page import floor_facts
from drivenav.report.site import write_report
from drivenav.settings import load_settings
from drivenav.types import Pose, SimConfig
from drivenav.viz.coverage import explored_floors
from drivenav.viz.episode import EpisodeMaterial, depth_to_rgb, load_episode, render_episode_pictures
from drivenav.viz.floors import floor_at, floors_of, pose_floors
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.topdown import (
    FLOOR_GAP,
    FLOOR_SIDE,
    HEADER,
    LEGEND_WIDTH,
    Canvas,
    draw_episode,
    floor_heading,
    segment_color,
)

SCENES = "storeys:1"  # seed 0: storeys/home_00000, two storeys
CROSS_FLOOR_SEED = 4  # its first cross-floor episode starts on the ground floor; the goal is upstairs


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The oracle on one episode that climbs from the ground floor to a goal on the upper floor."""
    out = tmp_path_factory.mktemp("floors")
    episodes = generate_episodes(SceneLibrary(SCENES, 0), 1, CROSS_FLOOR_SEED, storeys=Storeys(1.0))
    assert (episodes[0].info["start_floor"], episodes[0].info["goal_floors"]) == (0, [1])
    evaluate(episodes, RunSpec(EmbeddedSpec(SCENES, 0), load_settings("oracle")), out, show_progress=False)
    return out


@pytest.fixture(scope="module")
def material(run_dir: Path) -> EpisodeMaterial:
    loaded = load_episode(run_dir, "0")
    assert isinstance(loaded.scene, Building) and len(loaded.scene.storeys) == 2
    assert loaded.record is not None and loaded.record.success
    return loaded


def _building(material: EpisodeMaterial) -> Building:
    assert isinstance(material.scene, Building)
    return material.scene


def test_saved_trace_poses_carry_their_heights(material: EpisodeMaterial) -> None:
    trace = material.trace
    heights = trace.trace.heights
    assert len(heights) == len(trace) and heights[0] == 0.0 and heights[-1] > 2.5
    for step in (0, len(trace) // 2, len(trace) - 1):
        assert trace.pose(step).z == heights[step]
    assert trace.pose(len(trace) + 5).z == heights[-1]  # clamped like the position
    flat = EpisodeTrace("0", "flat", ((0.0, 0.0), (0.25, 0.0)), (0.0, 0.0))
    assert SavedTrace.of(flat, material.episode).pose(1) == Pose(0.25, 0.0, 0.0, 0.0)


def test_the_path_is_split_between_the_floors(material: EpisodeMaterial) -> None:
    building, trace = _building(material), material.trace
    on = pose_floors(building, trace)
    assert on[0] == 0 and on[-1] == 1
    assert np.all(np.diff(on) >= 0)  # the oracle climbs once
    assert list(floor_at(building, [0.0, 1.0, building.elevations[1]])) == [0, 0, 1]  # the stairs: the lower floor


def test_topdown_has_a_map_per_storey_with_the_path_on_each(material: EpisodeMaterial) -> None:
    building, episode, trace = _building(material), material.episode, material.trace
    picture = np.asarray(draw_episode(building, episode, trace, material.record))
    width, height = Canvas(building, FLOOR_SIDE).size
    assert picture.shape[:2] == (HEADER + height, 2 * width + FLOOR_GAP + LEGEND_WIDTH)
    path = np.all(picture == segment_color(0, 1), axis=-1)  # one segment: the oracle's path colour
    assert path[:, :width].sum() > 100 and path[:, width + FLOOR_GAP : 2 * width + FLOOR_GAP].sum() > 100
    ground, upper = floors_of(building)
    assert floor_heading(ground, episode, start=True) == "floor 0 (0.0 m): start"
    assert floor_heading(upper, episode, start=False) == f"floor 1 ({building.elevations[1]:.1f} m): goal"


def test_views_are_rendered_from_the_floor_the_agent_was_on(material: EpisodeMaterial, tmp_path: Path) -> None:
    paths = render_episode_pictures(material, tmp_path, video=False)
    sim = SimConfig()
    end = material.trace.pose(len(material.trace) - 1)
    assert floor_at(_building(material), end.z) == 1
    depth, _ = Renderer(_building(material), sim).render_geometry(end)
    shown = np.asarray(Image.open(next(p for p in paths if p.name.endswith("_end_view.png"))))
    assert np.array_equal(shown[:, sim.width : 2 * sim.width], depth_to_rgb(depth, sim.max_depth))
    ground, _ = Renderer(_building(material), sim).render_geometry(Pose(end.x, end.y, end.yaw))
    assert not np.array_equal(depth, ground)


def test_each_floor_is_explored_from_the_poses_on_it(material: EpisodeMaterial) -> None:
    building, trace = _building(material), material.trace
    explored = explored_floors(building, trace, SimConfig())
    on = pose_floors(building, trace)
    assert len(explored) == 2
    for floor, cells in enumerate(explored):
        seen = building.grid.cell_to_world(np.argwhere(cells))
        assert len(seen) > 100
        poses = trace.positions[on == floor]
        nearest = np.min(np.linalg.norm(seen[:, None, :] - poses[None, :, :], axis=-1), axis=1)
        assert nearest.max() <= 5.0 + building.grid.resolution


def test_the_episode_page_names_the_floors(run_dir: Path, material: EpisodeMaterial, tmp_path: Path) -> None:
    upper = f"{_building(material).elevations[1]:.1f} m"
    assert floor_facts(material.episode) == [
        ("start floor", "floor 0 (at 0.0 m)"),
        ("goal floors", f"floor 1 (view points at {upper})"),
        ("floor change needed", "yes"),
    ]
    write_report([run_dir], tmp_path / "site", ReportConfig(pictures=PictureChoice.ALL, workers=1))
    [page] = (tmp_path / "site" / "runs").glob("*/episodes/0.html")
    html = page.read_text(encoding="utf-8")
    assert "<dt>start floor</dt><dd>floor 0 (at 0.0 m)</dd>" in html
    assert '<figure class="topdown"><a href="../pictures/0_topdown.png">' in html


def _one_floor() -> tuple[Scene, EpisodeMaterial]:
    library = SceneLibrary("procedural:1", 0)
    scene = library.load(library.scene_ids[0])
    assert isinstance(scene, Scene)
    episode = generate_episodes(library, 1, seed=0)[0]
    x, y = episode.start_xy
    trace = EpisodeTrace(episode.episode_id, scene.scene_id, ((x, y), (x + 0.25, y), (x + 0.5, y)), (0.0, 0.0, 0.0))
    return scene, EpisodeMaterial(scene, episode, SavedTrace.of(trace, episode), None)


def test_a_one_floor_picture_is_as_it_was() -> None:
    scene, material = _one_floor()
    picture = draw_episode(scene, material.episode, material.trace)
    width, height = Canvas(scene).size
    assert picture.size == (width + LEGEND_WIDTH, height)
    assert floor_facts(material.episode) == []
    one_storey = Building(scene.scene_id, (Storey(scene, 0.0),))
    same = draw_episode(one_storey, material.episode, material.trace)
    assert np.array_equal(np.asarray(same), np.asarray(picture))
