"""Habitat's episode layouts without habitat-lab: export and read back, habitat-lab's keys and order, ids, and
one-line errors; the adapter's pure parts (config values, observation conventions)."""

from __future__ import annotations

import gzip
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import BENCHMARKS, LAYOUTS, OBJECTNAV_V1, OVON
from drivenav.envs.habitat.config import hydra_overrides, paper_values
from drivenav.envs.habitat.layouts import goals_key, read_split, scene_path, split_files, write_split
from drivenav.envs.habitat.observations import depth_in_metres, pose_from_gps_compass, to_observation
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.episodes import episode_to_dict, load_episodes, save_episodes
from drivenav.types import GEODESIC, SEMANTIC, SimConfig
from held import as_held


@pytest.fixture(scope="module")
def episodes(tmp_path_factory: pytest.TempPathFactory) -> list[Episode]:
    path = tmp_path_factory.mktemp("episodes") / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural", 0), 8, 4), path)
    return [as_held(episode) for episode in load_episodes(path)]


@pytest.fixture(scope="module")
def storeyed(tmp_path_factory: pytest.TempPathFactory) -> list[Episode]:
    """Episodes in homes of several storeys: starts and view points at their floors' heights, floor info."""
    path = tmp_path_factory.mktemp("storeyed") / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("storeys:3", 0), 12, 5, storeys=Storeys(0.5)), path)
    return [as_held(episode) for episode in load_episodes(path)]


def test_the_storeyed_set_has_heights_and_floor_changes(storeyed: list[Episode]) -> None:
    assert {e.start_height > 0.0 for e in storeyed} == {True, False}
    assert any(vp.height > 0.0 for e in storeyed for g in e.goals for vp in g.view_points)
    assert {e.info.get("cross_floor") for e in storeyed} == {True, False, None}  # None: a home of one storey


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("source", ["episodes", "storeyed"])
def test_export_reads_back_the_same_episodes(
    source: str, layout: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    """Every field comes back, heights and ``info``'s ``start_floor``, ``goal_floors`` and ``cross_floor`` too."""
    episodes: list[Episode] = request.getfixturevalue(source)
    split = tmp_path / "val" / "val.json.gz"
    write_split(episodes, split, layout)
    back = read_split(split, layout)
    by_id = {e.episode_id: episode_to_dict(e) for e in back}
    assert sorted(by_id) == sorted(e.episode_id for e in episodes)
    for episode in episodes:
        read = by_id[episode.episode_id]
        assert read["info"].pop("euclidean_distance") > 0.0  # added where missing (HM3D-OVON's statistics read it)
        assert read == episode_to_dict(episode)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_export_is_habitat_labs_layout_and_deterministic(episodes: list[Episode], layout: str, tmp_path: Path) -> None:
    first = write_split(episodes, tmp_path / "a" / "val" / "val.json.gz", layout)
    second = write_split(episodes, tmp_path / "b" / "val" / "val.json.gz", layout)
    assert [p.read_bytes() for p in first] == [p.read_bytes() for p in second]
    split = json.loads(gzip.decompress(first[0].read_bytes()))
    assert split["episodes"] == []
    if layout == OVON:  # HM3D-OVON's split file holds nothing; its content files' category maps are empty
        assert split == {"goals_by_category": {}, "episodes": []}
    else:
        maps = split["category_to_task_category_id"]
        assert maps == split["category_to_mp3d_category_id"] and len(maps) > 1
    content = json.loads(gzip.decompress(first[1].read_bytes()))
    episode = content["episodes"][0]
    assert episode["goals"] == []
    assert goals_key(episode["scene_id"], episode["object_category"]) in content["goals_by_category"]
    assert ("children_object_categories" in episode) == (layout == OVON)
    assert split_files(first[0]) == [first[0], *sorted(first[1:])]  # habitat-lab's reading order


def test_goals_key_and_scene_path_follow_habitat_lab() -> None:
    assert goals_key("hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb", "chair") == "TEEsavR23oF.basis.glb_chair"
    assert scene_path("data/scene_datasets/hm3d/a/a.glb", "/d/scene_datasets") == "/d/scene_datasets/hm3d/a/a.glb"
    assert scene_path("hm3d/a/a.glb", "/d/scene_datasets") == "/d/scene_datasets/hm3d/a/a.glb"


def test_ids_repeated_across_scenes_are_named_by_scene(episodes: list[Episode], tmp_path: Path) -> None:
    renumbered = [replace(e, episode_id="0") for e in episodes[:3]]  # as files numbered per scene would have it
    split = tmp_path / "val" / "val.json.gz"
    write_split(renumbered, split, OBJECTNAV_V1)
    ids = [e.episode_id for e in read_split(split, OBJECTNAV_V1)]
    assert len(set(ids)) == 3 and all(i.endswith(":0") for i in ids)


def test_a_missing_goals_key_is_one_line_naming_the_file(episodes: list[Episode], tmp_path: Path) -> None:
    split = tmp_path / "val" / "val.json.gz"
    content = write_split(episodes[:1], split, OVON)[1]
    data = json.loads(gzip.decompress(content.read_bytes()))
    data["goals_by_category"] = {}
    content.write_bytes(gzip.compress(json.dumps(data).encode()))
    with pytest.raises(InputError, match="goals_by_category") as error:
        read_split(split, OVON)
    assert str(content) in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize(("given", "read"), [("7", 7), ("-3", -1), ("\u00b2", -1), ("--5", -1), ("9" * 5000, -1)])
def test_a_goal_id_written_as_text_is_read_as_a_number_or_kept_out(
    episodes: list[Episode], tmp_path: Path, given: str, read: int
) -> None:
    """'²' passed ``str.isdigit`` and then ``int`` raised a traceback."""
    split = tmp_path / "val" / "val.json.gz"
    content = write_split(episodes[:1], split, OVON)[1]
    data = json.loads(gzip.decompress(content.read_bytes()))
    for goals in data["goals_by_category"].values():
        goals[0]["object_id"] = given
    content.write_bytes(gzip.compress(json.dumps(data).encode()))
    [episode] = read_split(split, OVON)
    assert episode.goals[0].object_id == read


def test_a_missing_split_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="split file"):
        read_split(tmp_path / "val" / "val.json.gz", OVON)


def test_paper_values_reach_habitat_lab_and_user_overrides_win() -> None:
    spec = HabitatSpec("hm3d-ovon", "val_unseen", "/data", ("habitat.simulator.turn_angle=15",))
    values = paper_values(spec, SimConfig())
    assert values["habitat.environment.max_episode_steps"] == "500"
    assert values["habitat.simulator.agents.main_agent.sim_sensors.depth_sensor.max_depth"] == "5"
    assert values["habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.position"] == "[0,0.88,0]"
    assert values["habitat.dataset.type"] == "drivenav-OVON-v1"  # HM3D-OVON's own "OVON-v1" is never replaced
    assert values["habitat.dataset.data_path"] == "'/data/datasets/ovon/hm3d/v1/{split}/{split}.json.gz'"  # OVON's
    assert paper_values(spec, SimConfig(), "OVON-v1")["habitat.dataset.type"] == "OVON-v1"
    overrides = hydra_overrides(spec, SimConfig())
    assert overrides[-1] == "habitat.simulator.turn_angle=15"
    assert "habitat.simulator.turn_angle=30" not in overrides


def test_spec_refuses_unknown_benchmarks_and_splits() -> None:
    with pytest.raises(InputError, match="--split"):
        HabitatSpec("mp3d", "val_seen", "/data")
    with pytest.raises(InputError, match="--config"):
        HabitatSpec("gibson", "val", "/data")
    assert HabitatSpec("mp3d", "val", "/d").provides == {GEODESIC}
    assert HabitatSpec("mp3d", "val", "/d", semantic=True).provides == {GEODESIC, SEMANTIC}
    assert all(bench.dataset_type in ("ObjectNav-v1", "drivenav-OVON-v1") for bench in BENCHMARKS.values())


def test_observation_conventions() -> None:
    sim = SimConfig(width=4, height=2)
    normalised = np.array([[[0.0], [1.0], [0.5], [1.5 / 4.5]]] * 2, dtype=np.float32)
    metres = depth_in_metres(normalised, sim)
    assert metres.dtype == np.float32 and metres.shape == (2, 4)
    assert metres[0].tolist() == pytest.approx([0.5, 5.0, 2.75, 2.0], abs=1e-6)
    assert metres[0, 0] == 0.5 and metres[0, 1] == 5.0  # exactly the clip values
    pose = pose_from_gps_compass(np.array([1.0, 2.0], np.float32), np.array([0.5], np.float32))
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((1.0, -2.0, 0.5))  # (forward, right) -> (x, left)
    rgba = np.zeros((2, 4, 4), np.uint8)
    raw = {"rgb": rgba, "depth": normalised, "gps": np.zeros(2, np.float32), "compass": np.array([math.pi])}
    observation = to_observation(raw, sim, 3, False)
    assert observation.rgb.shape == (2, 4, 3) and observation.semantic is None and observation.step == 3


def _cli_error(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main(list(argv)) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("drivenav: error:") and "\n" not in error
    return error


def test_habitat_command_line_errors_are_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    run = ["eval", "--agent", "oracle", "--episodes", "1", "--out", str(tmp_path / "r")]
    assert "--config" in _cli_error(capsys, *run, "--env", "habitat", "--split", "val")
    assert "--config" in _cli_error(capsys, *run, "--env", "habitat", "--config", "mp3d", "--config", "hm3d-v1")
    assert "--split" in _cli_error(capsys, *run, "--env", "habitat", "--config", "mp3d")
    assert "--data-dir" in _cli_error(capsys, *run, "--env", "habitat", "--config", "mp3d", "--split", "val")
    missing = str(tmp_path / "nowhere")
    habitat = [*run, "--env", "habitat", "--config", "mp3d", "--split", "val"]
    assert "--data-dir" in _cli_error(capsys, *habitat, "--data-dir", missing)
    assert "--split" in _cli_error(
        capsys, *run, "--env", "habitat", "--config", "mp3d", "--split", "x", "--data-dir", str(tmp_path)
    )
    assert "--set" in _cli_error(capsys, *run, "--set", "habitat.simulator.turn_angle=15")
    assert "habitat-lab" in _cli_error(capsys, *habitat, "--data-dir", str(tmp_path))  # not installed here


def test_episodes_export_command(episodes: list[Episode], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "episodes.json.gz"
    save_episodes(episodes, source)
    out = tmp_path / "datasets" / "ovon" / "hm3d" / "v1"
    assert (
        main(
            [
                "episodes",
                "export",
                "--episodes",
                str(source),
                "--format",
                "ovon",
                "--split",
                "val_seen",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert f"wrote {len(episodes)} episodes as ovon" in capsys.readouterr().out
    spec = HabitatSpec("hm3d-ovon", "val_seen", str(tmp_path))
    assert sorted(e.episode_id for e in spec.episodes()) == sorted(e.episode_id for e in episodes)
