"""HM3D-OVON's released files both ways, without habitat-lab: the released form read (text ids, children, synonym
goals, radius, scene dataset, HM3D scene paths) and written back field by field; drivenav's own episodes through
an export and back; the cases an export refuses; macOS metadata files skipped."""

from __future__ import annotations

import gzip
import json
import logging
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import OBJECTNAV_V1, OVON
from drivenav.envs.habitat.layouts import read_split, write_split
from drivenav.episode import Episode, ObjectGoal, ViewPoint, habitat_object_id, parse_object_id
from drivenav.errors import InputError
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.validation import Fields
from held import as_held
from ovon_fixture import fixture_files, read_documents, write_released

HM3D_CONFIG = "./data/scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json"


@pytest.fixture(scope="module")
def released(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_released(tmp_path_factory.mktemp("released") / "data")


@pytest.fixture(scope="module")
def own(tmp_path_factory: pytest.TempPathFactory) -> list[Episode]:
    """drivenav's generated episodes as a user's file holds them (synonyms and several goals among them), with
    coordinates as a Habitat layout holds them."""
    path = tmp_path_factory.mktemp("own") / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural", 0), 16, 7), path)
    return [as_held(episode) for episode in load_episodes(path)]


def test_the_released_form_reads_as_hm3d_ovon_means_it(released: Path) -> None:
    episodes = {e.episode_id: e for e in read_split(released, OVON)}
    assert sorted(episodes) == [f"house_0000{s}:{i}" for s, n in ((0, 4), (1, 2)) for i in range(n)]  # ids repeat
    kettle, chair, armchair, couch = (episodes[f"house_00000:{i}"] for i in range(4))
    assert kettle.scene_id == "hm3d/val/00800-house_00000/house_00000.basis.glb"  # unchanged
    assert kettle.scene_dataset_config == HM3D_CONFIG and "scene_dataset_config" not in kettle.info
    assert [(g.object_id, g.dataset_id) for g in kettle.goals] == [(87, None)]  # "kettle_87"
    assert kettle.goals[0].view_points[0].radius == 1.00923 and kettle.goals[0].view_points[0].iou == 0.0
    assert kettle.info == {"geodesic_distance": 6.75569, "euclidean_distance": 5.35093}
    # children: the armchairs and office chairs are goals of "chair" too, each keeping its category
    assert chair.children_object_categories == ("armchair", "office chair", "rocking chair")
    categories = [g.object_category for g in chair.goals]
    assert categories == ["chair"] * 5 + ["armchair"] * 3 + ["office chair"] * 2
    assert [g.object_id for g in chair.goals][5:] == [g.object_id for g in armchair.goals] + [52, 67]
    # a synonym episode: goals keyed and categorised by its text, ids the objects' own
    assert couch.object_category == "couch" and {g.object_category for g in couch.goals} == {"couch"}
    assert [(g.object_id, g.dataset_id) for g in couch.goals] == [(1, "sofa_1"), (11, "sofa_11"), (20, "sofa_20")]


def test_the_released_form_is_written_back_field_by_field(released: Path, tmp_path: Path) -> None:
    written = write_split(read_split(released, OVON), tmp_path / "out" / "val_seen" / "val_seen.json.gz", OVON)
    assert len(written) == 3
    assert read_documents(written[0]) == fixture_files()


def test_the_released_form_survives_drivenavs_own_file(released: Path, tmp_path: Path) -> None:
    """Read, saved as drivenav's episodes file, loaded, exported (``drivenav episodes export``): the fixture, every
    field and every digit of its coordinates."""
    source = tmp_path / "episodes.json.gz"
    save_episodes(read_split(released, OVON), source)
    out = tmp_path / "datasets" / "ovon" / "hm3d" / "v1"
    argv = ["episodes", "export", "--episodes", str(source), "--format", "ovon", "--split", "val_seen"]
    assert main([*argv, "--out", str(out)]) == 0
    assert read_documents(out / "val_seen" / "val_seen.json.gz") == fixture_files()


def test_macos_metadata_files_are_skipped_with_one_warning(
    released: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    split = write_released(tmp_path / "data")
    (split.parent / "content" / "._house_00000.json.gz").write_bytes(b"\x00\x05\x16\x07Mac OS X        ")
    with caplog.at_level(logging.WARNING, logger="drivenav.envs.habitat.layouts"):
        first, again = read_split(split, OVON), read_split(split, OVON)
    assert first == again == read_split(released, OVON)
    (warning,) = [r.getMessage() for r in caplog.records]
    assert "._house_00000.json.gz" in warning and str(split.parent / "content") in warning


def test_drivenavs_own_episodes_round_trip(own: list[Episode], tmp_path: Path) -> None:
    """Every field comes back (a synonym episode's goals under the canonical category); ``info`` gains the
    straight-line distance from the start to the nearest view point; a second export is the same bytes."""
    assert sum(bool(e.info["synonym"]) for e in own) >= 2
    first = write_split(own, tmp_path / "a" / "val" / "val.json.gz", OVON)
    back = read_split(first[0], OVON)  # in habitat-lab's order: by content file
    by_id = {e.episode_id: e for e in back}
    assert len(back) == len(by_id) == len(own)
    for source in own:
        read = by_id[source.episode_id]
        points = np.array([vp.position for goal in source.goals for vp in goal.view_points])
        nearest = float(np.min(np.linalg.norm(points - np.array(source.start_position), axis=1)))
        assert read.info["euclidean_distance"] == pytest.approx(nearest, abs=1e-5)
        assert replace(read, info={k: v for k, v in read.info.items() if k != "euclidean_distance"}) == source
    second = write_split(back, tmp_path / "b" / "val" / "val.json.gz", OVON)
    assert [p.read_bytes() for p in first] == [p.read_bytes() for p in second]


def test_a_synonym_episodes_goals_are_keyed_and_categorised_by_its_text(own: list[Episode], tmp_path: Path) -> None:
    synonym = next(e for e in own if e.info["synonym"])
    content = write_split([synonym], tmp_path / "val" / "val.json.gz", OVON)[1]
    document = json.loads(gzip.decompress(content.read_bytes()))
    (key,) = document["goals_by_category"]
    assert key == f"{synonym.scene_id.rsplit('/', 1)[-1]}_{synonym.object_category}"
    goals = document["goals_by_category"][key]
    assert {g["object_category"] for g in goals} == {synonym.object_category}
    canonical = synonym.info["canonical_category"]  # the id names the object: its own category and number
    assert [g["object_id"] for g in goals] == [f"{canonical}_{g.object_id}" for g in synonym.goals]


def test_an_export_loses_no_field_habitat_lab_reads(own: list[Episode], tmp_path: Path) -> None:
    content = write_split(own[:1], tmp_path / "val" / "val.json.gz", OVON)[1]
    document = json.loads(gzip.decompress(content.read_bytes()))
    (episode,) = document["episodes"]
    assert episode["scene_dataset_config"] == "default" and episode["children_object_categories"] == []
    assert (episode["start_room"], episode["shortest_paths"], episode["goals"]) == (None, None, [])
    assert set(document) == {
        "goals_by_category",
        "episodes",
        "category_to_task_category_id",
        "category_to_scene_annotation_category_id",
    }
    (goals,) = document["goals_by_category"].values()
    assert all(isinstance(g["object_id"], str) and g["object_id"].rsplit("_", 1)[1].isdigit() for g in goals)


def test_scenes_with_one_base_name_are_refused(own: list[Episode], tmp_path: Path) -> None:
    twin = [own[0], replace(own[1], scene_id=f"elsewhere/{own[0].scene_id.rsplit('/', 1)[-1]}")]
    with pytest.raises(InputError, match="distinct base names") as error:
        write_split(twin, tmp_path / "val" / "val.json.gz", OVON, source="eps.json.gz")
    assert str(error.value).startswith("eps.json.gz: field 'scene_id'") and own[0].scene_id in str(error.value)
    assert not (tmp_path / "val").exists()  # nothing half-written


def test_the_export_command_refuses_them_in_one_line(
    own: list[Episode], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "eps.json.gz"
    save_episodes([own[0], replace(own[1], scene_id="homes/" + own[0].scene_id.split("/")[-1])], source)
    argv = ["episodes", "export", "--episodes", str(source), "--format", OBJECTNAV_V1, "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith(f"drivenav: error: {source}: field 'scene_id'") and "\n" not in error


@pytest.mark.parametrize(
    ("value", "category", "expected"),
    [
        (7, "chair", (7, None)),
        ("chair_3", "chair", (3, None)),  # HM3D-OVON's form, written back from the category and number
        ("armchair_12", "chair", (12, "armchair_12")),  # another name: kept
        ("tv_monitor_305", "tv_monitor", (305, None)),  # underscores in the category
        ("chair_007", "chair", (7, "chair_007")),
        ("42", "chair", (42, "42")),
        ("chair", "chair", (-1, "chair")),  # no number: no instance
        ("chair_²", "chair", (-1, "chair_²")),
    ],
)
def test_object_ids(value: object, category: str, expected: tuple[int, str | None]) -> None:
    fields = Fields("f.json")
    assert parse_object_id(fields, "goals[0].object_id", value, category) == expected
    goal_id, dataset_id = expected
    if goal_id >= 0:
        goal = replace(read_goal(category), object_id=goal_id, dataset_id=dataset_id)
        assert habitat_object_id(goal) == (value if isinstance(value, str) else f"{category}_{value}")


@pytest.mark.parametrize("value", [1.5, True, "", None, ["chair_3"]])
def test_other_object_ids_are_one_line(value: object) -> None:
    with pytest.raises(InputError, match=r"f.json: field 'goals\[0\].object_id': expected an integer, or a text id"):
        parse_object_id(Fields("f.json"), "goals[0].object_id", value, "chair")


def read_goal(category: str) -> ObjectGoal:
    return ObjectGoal(0, category, (0.0, 0.0, 0.0), (ViewPoint((1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),))


def test_view_point_radius_and_text_ids_survive_drivenavs_own_file(released: Path, tmp_path: Path) -> None:
    episodes = read_split(released, OVON)
    path = tmp_path / "e.json.gz"
    save_episodes(episodes, path)
    loaded = load_episodes(path)
    assert loaded == episodes  # every field, every digit
    assert [[g.dataset_id for g in e.goals] for e in loaded] == [[g.dataset_id for g in e.goals] for e in episodes]
    radii = [vp.radius for e in loaded for g in e.goals for vp in g.view_points]
    assert radii == [vp.radius for e in episodes for g in e.goals for vp in g.view_points]
    assert all(vp.radius is not None for e in episodes for g in e.goals for vp in g.view_points)
    assert any(g.dataset_id is not None for e in episodes for g in e.goals)


def test_one_scene_and_category_with_two_sets_of_goals_is_refused(own: list[Episode], tmp_path: Path) -> None:
    first = own[0]
    other = replace(first, episode_id="other", goals=(replace(first.goals[0], object_id=999), *first.goals[1:]))
    with pytest.raises(InputError, match="the same goals in every episode") as error:
        write_split([first, other], tmp_path / "val" / "val.json.gz", OVON, source="eps.json.gz")
    assert "episode other" in str(error.value) and "\n" not in str(error.value)
