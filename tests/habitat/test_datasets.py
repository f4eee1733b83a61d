"""The two Habitat layouts as habitat-lab reads them: HM3D-OVON through drivenav's own dataset type (children
categories count for success, episode ids kept) and ObjectNav v1 through habitat-lab's own reader (which numbers
episodes per file; drivenav still finds each episode by its file id)."""

from __future__ import annotations

import gzip
import json
from dataclasses import replace
from pathlib import Path

import pytest
from worlds import SIM_OVERRIDE, export, settings_for

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import BENCHMARKS
from drivenav.envs.habitat.env import HabitatEnv
from drivenav.envs.habitat.layouts import goals_key, scene_name
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode, ObjectGoal, ViewPoint, coordinates, goal_to_dict
from drivenav.types import Action


def _write(path: Path, payload: dict[str, object]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with gzip.open(path, "wt", encoding="utf-8") as handle:
        json.dump(payload, handle)


def _ovon_split(data_dir: Path, episode: Episode) -> HabitatSpec:
    """Two episodes from one start: "sofa" (far goals) with child "armchair" (a view point at the start), and
    "sofa" alone. Ids are text the reader must keep."""
    child = ObjectGoal(777, "armchair", episode.start_position, (ViewPoint(episode.start_position, (0, 0, 0, 1)),))
    scene = episode.scene_id
    common = {
        "scene_id": scene,
        "start_position": coordinates(episode.start_position),
        "start_rotation": coordinates(episode.start_rotation),
        "object_category": "sofa",
        "goals": [],
        "info": {"geodesic_distance": 1.0},
    }
    content = {
        "episodes": [
            {**common, "episode_id": "with-child", "children_object_categories": ["armchair"]},
            {**common, "episode_id": "alone", "children_object_categories": []},
        ],
        "goals_by_category": {
            goals_key(scene, "sofa"): [goal_to_dict(g) for g in episode.goals],
            goals_key(scene, "armchair"): [{**goal_to_dict(child), "radius": 0.5}],
        },
    }
    root = data_dir / Path(BENCHMARKS["hm3d-ovon"].data_path.format(split="val_unseen")).parent
    _write(root / "val_unseen.json.gz", {"episodes": [], "category_to_task_category_id": {}})
    _write(root / "content" / f"{scene_name(scene)}.json.gz", content)
    return HabitatSpec("hm3d-ovon", "val_unseen", str(data_dir), (SIM_OVERRIDE,))


@pytest.fixture(scope="module")
def generated() -> Episode:
    return generate_episodes(SceneLibrary("procedural", 0), 1, 5)[0]


def test_ovon_children_categories_count_for_success(generated: Episode, tmp_path: Path) -> None:
    spec = _ovon_split(tmp_path, generated)
    env = HabitatEnv(spec, settings_for("oracle", "hm3d-ovon").sim)
    try:
        outcomes = {}
        for episode in spec.episodes():
            env.reset(episode)
            env.step(Action.STOP)
            outcomes[episode.episode_id] = env.measures()
            assert env.habitat_env.current_episode.episode_id == episode.episode_id  # kept, not renumbered
    finally:
        env.close()
    assert outcomes["with-child"].success == 1 and outcomes["with-child"].distance_to_goal < 0.05  # one grid cell
    assert outcomes["alone"].success == 0 and outcomes["alone"].distance_to_goal > 1.0


def test_ovon_reader_resolves_children_and_keeps_ids(generated: Episode, tmp_path: Path) -> None:
    spec = _ovon_split(tmp_path, generated)
    with_child, alone = spec.episodes()
    assert (with_child.episode_id, alone.episode_id) == ("with-child", "alone")
    assert len(with_child.goals) == len(alone.goals) + 1
    assert with_child.goals[-1].object_id == 777


def test_objectnav_v1_episodes_found_by_file_id_though_habitat_lab_renumbers(tmp_path: Path) -> None:
    pool = generate_episodes(SceneLibrary("procedural", 0), 6, 3)
    scene = pool[0].scene_id
    same_scene = [replace(e, episode_id=f"ep-{k}") for k, e in enumerate(pool) if e.scene_id == scene]
    others = [replace(e, episode_id=f"ep-{k}") for k, e in enumerate(pool) if e.scene_id != scene]
    spec = export([*same_scene, *others], tmp_path / "data", "hm3d-v1")
    env = HabitatEnv(spec, settings_for("oracle", "hm3d-v1").sim)
    try:
        for episode in reversed(spec.episodes()):
            env.reset(episode)
            found = env.habitat_env.current_episode
            assert found.episode_id.isdigit()  # habitat-lab's index within its content file
            assert list(found.start_position) == pytest.approx(list(episode.start_position))
            assert found.object_category == episode.object_category
    finally:
        env.close()
    assert {e.episode_id for e in spec.episodes()} == {e.episode_id for e in [*same_scene, *others]}
