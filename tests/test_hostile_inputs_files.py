"""Hostile episode files and scenes: each answered with one line naming the file and the field, exit 2, before any
episode runs (never a silently dropped scene, a null distance or a negative SPL)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.geodesic import largest_component
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import world_to_habitat
from drivenav.errors import InputError
from drivenav.eval.episodes import episode_to_dict, load_episodes
from drivenav.types import SimConfig
from drivenav.validation import read_json
from test_rosmap import write_map

SCENES = "procedural:1"


def _write(path: Path, payload: dict[str, Any]) -> Path:
    path.write_bytes(gzip.compress(json.dumps(payload).encode()))
    return path


def _episodes(count: int = 2) -> list[dict[str, Any]]:
    return [episode_to_dict(e) for e in generate_episodes(SceneLibrary(SCENES, 0), count, 0)]


def _refused(capsys: pytest.CaptureFixture[str], tmp_path: Path, episodes: str, scenes: str, *words: str) -> None:
    out = tmp_path / "run"
    args = ["eval", "--agent", "random", "--scenes", scenes, "--episodes", episodes, "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    assert not (out / "episodes.jsonl").exists()


def _refused_file(capsys: pytest.CaptureFixture[str], tmp_path: Path, payload: dict[str, Any], *words: str) -> None:
    path = _write(tmp_path / "eps.json.gz", payload)
    _refused(capsys, tmp_path, str(path), SCENES, str(path), *words)


# ------------------------------------------------------------------------------------------------ episode files


def test_an_empty_episode_list(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _refused_file(capsys, tmp_path, {"episodes": []}, "'episodes'", "a non-empty list of episodes")


def test_duplicate_episode_ids(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first, second = _episodes()
    second["episode_id"] = first["episode_id"]
    words = ("'episodes[1].episode_id'", "episodes[0] has it", repr(first["episode_id"]))
    _refused_file(capsys, tmp_path, {"episodes": [first, second]}, *words)


def test_a_habitat_content_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episode = {k: v for k, v in _episodes(1)[0].items() if k != "goals"}
    payload = {"episodes": [episode], "goals_by_category": {"scene.basis.glb_chair": []}}
    _refused_file(capsys, tmp_path, payload, "goals_by_category", "--env habitat")


def test_a_habitat_split_file_with_content_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "content").mkdir()
    _write(tmp_path / "content" / "scene.json.gz", {"episodes": _episodes(1), "goals_by_category": {}})
    _refused_file(capsys, tmp_path, {"episodes": []}, "'episodes'", "split file", "content/", "--env habitat")


def test_a_habitat_split_file_copied_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    payload = {"episodes": [], "category_to_task_category_id": {"chair": 0}}
    _refused_file(capsys, tmp_path, payload, "'episodes'", "split file", "--env habitat")


def test_an_hm3d_ovon_split_file_copied_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    payload = {"goals_by_category": {}, "episodes": []}  # as HM3D-OVON's released split files are
    _refused_file(capsys, tmp_path, payload, "'episodes'", "split file", "--env habitat")


def test_a_view_point_off_the_navigable_area(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episode = _episodes(1)[0]
    episode["goals"][0]["view_points"][0]["agent_state"]["position"] = [-50.0, 0.0, 50.0]
    words = ("'episodes[0].goals[0].view_points[0].agent_state.position'", "navigable", "[-50.0, 0.0, 50.0]")
    _refused_file(capsys, tmp_path, {"episodes": [episode]}, *words)


def _two_rooms(directory: Path) -> Path:
    """An 8 m x 4 m map split by a wall: a large room (x < 5.5 m) with a chair, a small one with a plant."""
    image = np.full((80, 160), FREE)
    image[[0, -1], :] = image[:, [0, 110, -1]] = WALL
    scene = write_map(directory, image, resolution=0.05, origin=[0.0, 0.0, 0.0])
    objects = [
        {"category": "chair", "center": [1.0, 2.0], "size": [0.5, 0.5, 0.9]},
        {"category": "plant", "center": [7.0, 2.0], "size": [0.3, 0.3, 0.8]},
    ]
    (scene / "objects.json").write_text(json.dumps({"objects": objects}))
    return scene


@pytest.mark.parametrize(
    ("move", "field"),
    [
        (lambda e, p: e["goals"][0]["view_points"][0]["agent_state"].update(position=p), "goals[0].view_points[0]"),
        (lambda e, p: e.update(start_position=p), "start_position"),
    ],
)
def test_a_goal_the_start_cannot_reach(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], move: Any, field: str
) -> None:
    scene = _two_rooms(tmp_path / "rooms")
    library, sim = SceneLibrary(str(scene)), SimConfig()
    navigable = library.load("rooms").navigable_grid(sim.agent_radius, sim.agent_height)
    row, col = library.load("rooms").grid.world_to_cell((7.0, 1.0))
    assert navigable[row, col] and not largest_component(navigable)[row, col]  # navigable, in the small room
    (episode,) = [episode_to_dict(e) for e in generate_episodes(library, 1, 0)]
    assert episode["info"]["canonical_category"] == "chair"  # the plant's room is closed off: no episode for it
    move(episode, list(world_to_habitat(7.0, 1.0)))
    path = _write(tmp_path / "eps.json.gz", {"episodes": [episode]})
    words = (f"'episodes[0].{field}", "a navigable position the agent can reach in rooms")
    _refused(capsys, tmp_path, str(path), str(scene), str(path), *words)


def test_a_geodesic_distance_the_world_disagrees_with(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episode = _episodes(1)[0]
    true = episode["info"]["geodesic_distance"]
    episode["info"]["geodesic_distance"] = round(1.2 * true, 4)  # today's SPL would have trusted it
    words = ("'episodes[0].info.geodesic_distance'", f"{true:.2f} m within 10%")
    _refused_file(capsys, tmp_path, {"episodes": [episode]}, *words)


def test_a_geodesic_distance_within_tolerance_is_accepted(tmp_path: Path) -> None:
    episode = _episodes(1)[0]
    episode["info"]["geodesic_distance"] = round(1.05 * episode["info"]["geodesic_distance"], 4)
    path = _write(tmp_path / "eps.json.gz", {"episodes": [episode]})
    args = ["eval", "--agent", "oracle", "--scenes", SCENES, "--episodes", str(path), "--out", str(tmp_path / "r")]
    assert main(args) == 0
    record = json.loads((tmp_path / "r" / "episodes.jsonl").read_text())
    assert record["geodesic_distance"] == pytest.approx(episode["info"]["geodesic_distance"] / 1.05, abs=0.01)
    assert 0.0 < record["spl"] <= 1.0  # the world's own start distance, as habitat-lab


# ------------------------------------------------------------------------------------------------ episodes stats


def _stats_refused(capsys: pytest.CaptureFixture[str], path: Path, *words: str) -> None:
    assert main(["episodes", "stats", str(path), "--scenes", "procedural", "--json"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert not captured.out  # no figures of a file the world disagrees with
    for word in (str(path), *words):
        assert word in err, err


def test_episodes_stats_refuses_a_geodesic_distance_the_world_disagrees_with(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    episode = _episodes(1)[0]
    true = episode["info"]["geodesic_distance"]
    episode["info"]["geodesic_distance"] = 100.0  # eval refuses it; stats reported it as the mean
    path = _write(tmp_path / "eps.json.gz", {"episodes": [episode]})
    _stats_refused(capsys, path, "'episodes[0].info.geodesic_distance'", f"{true:.2f} m within 10%", "100.0")


def test_episodes_stats_refuses_a_start_inside_a_wall(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first, second = _episodes(2)
    second["start_position"] = [0.0, 0.0, 0.0]  # the house's corner: outside its walls
    path = _write(tmp_path / "eps.json.gz", {"episodes": [first, second]})
    _stats_refused(capsys, path, "'episodes[1].start_position'", "a navigable position the agent can reach")


def test_episodes_stats_with_no_check_says_it_did_not_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episode = _episodes(1)[0]
    episode["info"]["geodesic_distance"] = 100.0
    path = _write(tmp_path / "eps.json.gz", {"episodes": [episode]})
    assert main(["episodes", "stats", str(path), "--scenes", "procedural", "--json", "--no-check"]) == 0
    captured = capsys.readouterr()
    assert f"{path} not checked against the scenes (--no-check)" in captured.err
    [figures] = json.loads(captured.out)["episode_sets"]
    assert figures["geodesic"]["mean"] == 100.0  # the file's own figure, as the note says


# ------------------------------------------------------------------------------------------------ keys, encodings


def _text_file(tmp_path: Path, text: str, name: str = "eps.json.gz") -> Path:
    path = tmp_path / name
    path.write_bytes(gzip.compress(text.encode()))
    return path


@pytest.mark.parametrize(
    ("first", "second"),
    [("[E]", "5"), ("5", "[E]"), ("[E]", "[E]"), ("[E]", "null")],
)
def test_a_second_episodes_key_is_refused_whatever_either_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], first: str, second: str
) -> None:
    """The stream ran the first array where ``json`` keeps the second value: the two readings must not differ."""
    episode = json.dumps(_episodes(1)[0])
    text = f'{{"episodes": {first}, "episodes": {second}}}'.replace("E", episode)
    path = _text_file(tmp_path, text)
    _refused(capsys, tmp_path, str(path), SCENES, str(path), "'episodes'", "one 'episodes' key", "two")


def test_a_top_level_key_given_twice_is_refused_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = '{"version": 1, "episodes": ' + json.dumps(_episodes(1)) + ', "version": 2}'
    path = _text_file(tmp_path, text)
    _refused(capsys, tmp_path, str(path), SCENES, str(path), "'version'", "one 'version' key")


@pytest.mark.parametrize("inside", ["episode", "info", "goal"])
def test_a_key_given_twice_inside_an_episode_is_refused_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], inside: str
) -> None:
    first, second = _episodes(2)
    text = json.dumps(second)
    if inside == "episode":  # the second copy is the one json.loads would keep
        text = text.replace('"scene_id": ', '"scene_id": "elsewhere", "scene_id": ', 1)
        key = "scene_id"
    elif inside == "info":
        text = text.replace('"synonym": ', '"geodesic_distance": 99.0, "synonym": ', 1)
        key = "geodesic_distance"
    else:
        text = text.replace('"object_id": ', '"object_id": 7, "object_id": ', 1)
        key = "object_id"
    path = _text_file(tmp_path, '{"episodes": [' + json.dumps(first) + ", " + text + "]}")
    words = ("'episodes[1]'", "each key once in a JSON object", f"'{key}' twice")
    _refused(capsys, tmp_path, str(path), SCENES, str(path), *words)


def test_a_key_given_twice_in_a_small_document_is_refused(tmp_path: Path) -> None:
    """Whole documents (objects.json, run.json, the vocabulary) are read by the same reader's other half."""
    path = tmp_path / "objects.json"
    path.write_text('{"objects": [{"category": "chair", "category": "plant"}]}')
    with pytest.raises(InputError, match="expected each key once in a JSON object, got \"'category' twice\""):
        read_json(path)


@pytest.mark.parametrize("compress", [True, False])
def test_an_episodes_file_with_a_byte_order_mark_reads_as_without(tmp_path: Path, compress: bool) -> None:
    """RFC 8259 lets a reader skip a UTF-8 byte order mark (Windows editors write one); it was reported as
    "Expecting value at line 1, column 1"."""
    data = json.dumps({"episodes": _episodes(2)}).encode()
    plain, marked = tmp_path / "plain.json", tmp_path / "marked.json"
    plain.write_bytes(data)
    marked.write_bytes(gzip.compress(b"\xef\xbb\xbf" + data) if compress else b"\xef\xbb\xbf" + data)
    assert load_episodes(marked) == load_episodes(plain)
    assert read_json(marked) == read_json(plain)


# ------------------------------------------------------------------------------------------------ scenes

FREE, WALL, UNKNOWN = 254, 0, 205


@pytest.mark.parametrize(
    ("image", "case"),
    [
        (np.full((1, 1), FREE), "a 1x1 image"),
        (np.full((40, 40), WALL), "all occupied"),
        (np.full((40, 40), UNKNOWN), "all unknown"),
    ],
)
def test_a_map_the_agent_fits_nowhere_in(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], image: np.ndarray, case: str
) -> None:
    scene = write_map(tmp_path / "tiny", image, resolution=0.05, origin=[0.0, 0.0, 0.0])
    _refused(capsys, tmp_path, "2", str(scene), str(scene / "map.yaml"), "'image'", "free space an agent")


def test_a_map_at_a_micrometre_per_pixel(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = write_map(tmp_path / "tiny", np.full((20, 20), FREE), resolution=1e-6, origin=[0.0, 0.0, 0.0])
    assert "resolution: 1e-06\n" in (scene / "map.yaml").read_text()  # a number in YAML 1.2 and ROS, text in 1.1
    _refused(capsys, tmp_path, "2", str(scene), str(scene / "map.yaml"), "'image'", "free space an agent")


def test_a_map_whose_objects_list_is_empty(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = write_map(tmp_path / "empty", np.full((80, 80), FREE), resolution=0.05, origin=[0.0, 0.0, 0.0])
    (scene / "objects.json").write_text(json.dumps({"objects": [], "rooms": []}))
    words = ("'objects'", "0 objects, none reachable")
    _refused(capsys, tmp_path, "2", str(scene), str(scene / "objects.json"), *words)


def test_a_room_with_one_cell_to_stand_on(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    image = np.full((17, 17), WALL)
    image[4:13, 4:13] = FREE  # 0.45 m square: one cell is 0.18 m clear of the walls, and it sees the picture
    scene = write_map(tmp_path / "closet", image, resolution=0.05, origin=[0.0, 0.0, 0.0])
    picture = {"category": "picture", "center": [0.575, 0.425], "size": [0.05, 0.05, 0.2], "elevation": 0.95}
    (scene / "objects.json").write_text(json.dumps({"objects": [picture]}))
    words = ("'objects'", "a start 1-30 m by geodesic distance")
    _refused(capsys, tmp_path, "1", str(scene), str(scene / "objects.json"), *words)


def test_a_map_whose_grid_would_need_more_than_2_gib(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = write_map(tmp_path / "huge", np.full((20, 20), FREE), resolution=1e6, origin=[0.0, 0.0, 0.0])
    _refused(capsys, tmp_path, "2", str(scene), str(scene / "map.yaml"), "'resolution'", "fits in 2 GiB")


def test_a_map_yaml_with_a_key_given_twice_is_refused_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """PyYAML keeps the second value and ROS's yaml-cpp the first: the two would build different scenes."""
    scene = write_map(tmp_path / "twice", np.full((80, 80), FREE), resolution=0.05, origin=[0.0, 0.0, 0.0])
    yaml_file = scene / "map.yaml"
    yaml_file.write_text(yaml_file.read_text() + "resolution: 0.5\n")
    line = len(yaml_file.read_text().splitlines())
    _refused(capsys, tmp_path, "2", str(scene), str(yaml_file), "'resolution'", f"the key again at line {line}")
