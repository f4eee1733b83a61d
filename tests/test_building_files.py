"""Buildings from files (drivenav.envs.embedded.building_files): building.yaml, its floor plans and staircases, the
scene library's building directories, the checks of episodes in a building, and one line with exit 2 for bad input.

The data: tests/data/buildings/two_floors, two 8 x 6 m floors 3 m apart at 5 cm, joined by one straight flight along
the south wall (x 1.5 to 5.25 m, y 0.1 to 1.1 m); the ground floor has an objects.json, the upper one has none.
"""

from __future__ import annotations

import gzip
import json
import shutil
from collections.abc import Callable
from copy import deepcopy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from PIL import Image

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.building_files import BUILDING_FILE, load_building, read_building_yaml
from drivenav.envs.embedded.levels import box_cells
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.terrain import terrain_of
from drivenav.episode import world_to_habitat
from drivenav.errors import InputError
from drivenav.eval.episodes import episode_to_dict, load_episodes, validate_for_scenes
from drivenav.types import SimConfig
from drivenav.validation import read_yaml
from test_rosmap import write_map

BUILDINGS = Path(__file__).parent / "data" / "buildings"
TWO_FLOORS = BUILDINGS / "two_floors"
SIM = SimConfig()
BASE: dict[str, Any] = {
    "storeys": [{"plan": "ground", "elevation": 0.0}, {"plan": "upper/map.yaml", "elevation": 3.0}],
    "stairs": [
        {"lower": 0, "flights": [{"foot": [1.5, 0.6], "heading": 0, "width": 1.0, "risers": 16, "going": 0.25}]}
    ],
}
"""The content of tests/data/buildings/two_floors/building.yaml, which the tests below vary."""
DOCS = Path(__file__).parents[1] / "docs" / "scenes.md"


def _documented() -> dict[str, Any]:
    """The building.yaml of docs/scenes.md's example: two_floors' plans, its stairs in two flights with a landing."""
    block = DOCS.read_text().split("# my_house/building.yaml\n", 1)[1].split("```", 1)[0]
    doc: dict[str, Any] = yaml.safe_load(block)
    return doc


def _building_dir(
    tmp_path: Path, change: Callable[[dict[str, Any]], object] = lambda doc: None, base: dict[str, Any] = BASE
) -> Path:
    """A copy of two_floors whose building.yaml is ``base`` changed by ``change``."""
    directory = tmp_path / "two_floors"
    shutil.copytree(TWO_FLOORS, directory)
    doc = deepcopy(base)
    change(doc)
    (directory / BUILDING_FILE).write_text(yaml.safe_dump(doc))
    return directory


def _flight(doc: dict[str, Any]) -> dict[str, Any]:
    flight: dict[str, Any] = doc["stairs"][0]["flights"][0]
    return flight


def _refused(call: Callable[[], object], source: Path, field: str, *words: str) -> InputError:
    with pytest.raises(InputError) as info:
        call()
    error = info.value
    assert error.source == str(source) and error.field == field, str(error)
    assert "\n" not in str(error)
    for word in words:
        assert word in str(error), str(error)
    return error


# ------------------------------------------------------------------------------------------------------ loading


def test_the_data_is_the_base_building() -> None:
    assert read_yaml(TWO_FLOORS / BUILDING_FILE) == BASE


def test_the_loader_gives_the_storeys_and_the_stairs() -> None:
    building = load_building(TWO_FLOORS)
    assert building.scene_id == "two_floors" and building.source == str(TWO_FLOORS / BUILDING_FILE)
    assert building.elevations == (0.0, 3.0)
    assert building.grid.shape == (120, 160) and building.grid.origin == (0.0, 0.0)
    [stair] = building.stairs
    [flight] = stair.flights
    assert stair.lower == 0 and stair.landings == ()
    assert (flight.foot, flight.heading, flight.width, flight.risers, flight.going) == ((1.5, 0.6), 0, 1.0, 16, 0.25)
    assert flight.riser == pytest.approx(3.0 / 16) and flight.base == 0.0 and flight.top == pytest.approx(3.0)
    assert flight.rect() == pytest.approx((1.5, 0.1, 5.25, 1.1))
    assert building.storeys[0].plan.ceiling_height == pytest.approx(3.0 - building.slab)


def test_objects_come_from_objects_json_or_are_placed_clear_of_the_stairs() -> None:
    building = load_building(TWO_FLOORS)
    ground, upper = (storey.plan.objects for storey in building.storeys)
    assert [(o.instance_id, o.category) for o in ground] == [(1, "sofa"), (2, "piano"), (3, "refrigerator")]
    assert upper and [o.instance_id for o in upper] == list(range(4, 4 + len(upper)))  # numbered on, storey by storey
    assert building.storeys[0].plan.rooms[1].name == "kitchen"
    keep_clear = building.holes[1] | box_cells(building.grid, building.railings[1])
    upper_plan = building.storeys[1].plan
    assert not (upper_plan.obstacle_grid(SIM.agent_height) & ~(upper_plan.structure > 0) & keep_clear).any()
    assert load_building(TWO_FLOORS).storeys[1].plan.objects == upper  # placed from the building's id alone


def test_the_reachable_area_spans_both_floors() -> None:
    terrain = terrain_of(load_building(TWO_FLOORS), SIM)
    assert terrain.reachable[0].sum() > 10_000 and terrain.reachable[1].sum() > 10_000
    assert terrain.on_reachable(1.2, 0.6, 0.0) and terrain.on_reachable(5.6, 0.6, 3.0)  # either end of the stairs
    assert terrain.place(3.375, 0.6, 1.5) == pytest.approx(1.5, abs=0.01)  # half way up the ramp
    assert not terrain.on_reachable(3.375, 0.6, 3.0)  # the stairwell upstairs
    distance = terrain.field([(7.0, 5.0, 3.0)]).at(7.0, 5.0, 0.0)  # upstairs, right above
    assert 10.0 < distance < 20.0


def test_the_documented_staircase_with_a_landing_derives_its_heights(tmp_path: Path) -> None:
    def derived(doc: dict[str, Any]) -> None:
        del doc["stairs"][0]["flights"][0]["riser"], doc["stairs"][0]["landings"][0]["height"]

    building = load_building(_building_dir(tmp_path, derived, _documented()))
    assert building.stairs == load_building(_building_dir(tmp_path / "as written", base=_documented())).stairs
    first, second = building.stairs[0].flights
    [landing] = building.stairs[0].landings
    assert first.base == 0.0 and landing.height == pytest.approx(1.5) and second.base == landing.height
    assert second.top == pytest.approx(3.0)
    terrain = terrain_of(building, SIM)
    assert terrain.on_reachable(3.75, 0.6, 1.5) and terrain.on_reachable(6.4, 0.6, 3.0)
    assert np.isfinite(terrain.field([(7.0, 5.0, 3.0)]).at(1.0, 3.0, 0.0))


# ------------------------------------------------------------------------------------------------ the library


def test_the_library_finds_buildings_as_it_finds_map_scenes(tmp_path: Path) -> None:
    assert SceneLibrary(str(BUILDINGS)).scene_ids == ["two_floors"]
    for spec in (TWO_FLOORS, TWO_FLOORS / BUILDING_FILE):
        library = SceneLibrary(str(spec))
        assert library.scene_ids == ["two_floors"] and isinstance(library.load("two_floors"), Building)
    folder = tmp_path / "scenes"
    shutil.copytree(TWO_FLOORS, folder / "two_floors")
    write_map(folder / "flat", np.full((40, 40), 254))
    library = SceneLibrary(str(folder))
    assert library.scene_ids == ["flat", "two_floors"]
    assert not isinstance(library.load("flat"), Building) and isinstance(library.load("two_floors"), Building)


def test_a_folder_refuses_a_broken_building_at_once(tmp_path: Path) -> None:
    building = _building_dir(tmp_path, lambda doc: doc["storeys"][1].update(elevation=1.0))
    _refused(lambda: SceneLibrary(str(tmp_path)), building / BUILDING_FILE, "storeys[1].elevation")


def test_the_oracle_reaches_goals_on_the_other_floor(tmp_path: Path) -> None:
    episodes = tmp_path / "eps.json.gz"
    generate = ["episodes", "generate", "--scenes", str(BUILDINGS), "--num", "3", "--cross-floor", "1"]
    assert main([*generate, "--out", str(episodes)]) == 0
    assert all(e.info["cross_floor"] is True for e in load_episodes(episodes))
    out = tmp_path / "run"
    assert (
        main(["eval", "--agent", "oracle", "--scenes", str(BUILDINGS), "--episodes", str(episodes), "--out", str(out)])
        == 0
    )
    records = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert len(records) == 3 and all(r["success"] == 1 and r["stop_reason"] == "target_reached" for r in records)


# --------------------------------------------------------------------------------------------- building.yaml


CASES: list[tuple[str, Callable[[dict[str, Any]], object], str, tuple[str, ...]]] = [
    ("a staircase from the top storey", lambda d: d["stairs"][0].update(lower=1), "stairs[0].lower", ("0 to 0",)),
    ("a staircase from no storey", lambda d: d["stairs"][0].update(lower=-1), "stairs[0].lower", ()),
    ("risers short of the floor", lambda d: _flight(d).update(riser=0.15), "stairs[0].flights", ("2.400 m",)),
    ("a riser too high", lambda d: _flight(d).update(risers=12, riser=0.25), "stairs[0].flights[0].riser", ("0.2",)),
    ("too few risers", lambda d: _flight(d).update(risers=14), "stairs[0].flights[0].risers", ("0.2 m",)),
    ("too steep", lambda d: _flight(d).update(going=0.15), "stairs[0].flights[0].going", ("45 degrees",)),
    ("an odd heading", lambda d: _flight(d).update(heading=45), "stairs[0].flights[0].heading", ()),
    ("one tread", lambda d: _flight(d).update(risers=1), "stairs[0].flights[0].risers", ()),
    ("an unknown key", lambda d: _flight(d).update(base=0.0), "stairs[0].flights[0].base", ("unknown key",)),
    ("floors too close", lambda d: d["storeys"][1].update(elevation=2.0), "storeys[1].elevation", ("2.4 m",)),
    ("floors in the wrong order", lambda d: d["storeys"].reverse(), "storeys[0].elevation", ("ground floor",)),
    ("a missing plan", lambda d: d["storeys"][1].update(plan="attic"), "storeys[1].plan", ("'attic'",)),
    ("no storeys", lambda d: d.update(storeys=[]), "storeys", ()),
    (
        "a landing too many",
        lambda d: d["stairs"][0].update(landings=[{"rect": [0, 0, 1, 1]}]),
        "stairs[0].landings",
        (),
    ),
]


@pytest.mark.parametrize(("change", "field", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_a_broken_building_yaml(
    tmp_path: Path, change: Callable[[dict[str, Any]], object], field: str, words: tuple[str, ...]
) -> None:
    directory = _building_dir(tmp_path, change)
    _refused(lambda: read_building_yaml(directory / BUILDING_FILE), directory / BUILDING_FILE, field, *words)


@pytest.mark.parametrize(
    ("landing", "field", "words"),
    [
        ({"rect": [3.5, 0.1, 4.25, 1.1]}, "stairs[0].landings[0].rect", ("top edge of flights[0]",)),
        ({"rect": [3.25, 0.1, 4.0, 1.1]}, "stairs[0].landings[0].rect", ("foot edge of flights[1]",)),
        ({"rect": [3.25, 0.1, 4.25, 1.1], "height": 1.2}, "stairs[0].landings[0].height", ("1.500 m",)),
        ({"rect": [4.25, 0.1, 3.25, 1.1]}, "stairs[0].landings[0].rect", ("x0 < x1",)),
    ],
)
def test_a_landing_that_joins_no_flights(
    tmp_path: Path, landing: dict[str, Any], field: str, words: tuple[str]
) -> None:
    directory = _building_dir(tmp_path, lambda doc: doc["stairs"][0].update(landings=[landing]), _documented())
    _refused(lambda: read_building_yaml(directory / BUILDING_FILE), directory / BUILDING_FILE, field, *words)


# ------------------------------------------------------------------------------------------- against the plans


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda d: _flight(d).update(foot=[0.3, 0.6]), "stairs[0].flights[0].foot", ("before the first riser", "wall")),
        (lambda d: _flight(d).update(foot=[4.0, 0.6]), "stairs[0].flights[0]", ("beyond the top edge", "wall")),
        (lambda d: _flight(d).update(foot=[5.0, 0.6]), "stairs[0].flights[0]", ("over free floor", "off the map")),
        (lambda d: _flight(d).update(width=1.2), "stairs[0].flights[0]", ("over free floor of storeys[0]", "wall")),
    ],
    ids=["foot at a wall", "top at a wall", "off the map", "over a wall"],
)
def test_stairs_that_end_in_a_wall(
    tmp_path: Path, change: Callable[[dict[str, Any]], object], field: str, words: tuple[str, ...]
) -> None:
    directory = _building_dir(tmp_path, change)
    _refused(lambda: load_building(directory), directory / BUILDING_FILE, field, *words)


def test_floor_plans_on_two_grids(tmp_path: Path) -> None:
    directory = _building_dir(tmp_path)
    upper = directory / "upper" / "map.yaml"
    upper.write_text(upper.read_text().replace("origin: [0.0, 0.0, 0.0]", "origin: [0.5, 0.0, 0.0]"))
    _refused(lambda: load_building(directory), upper, "origin", "[0.0, 0.0]", "one grid")
    upper.write_text(upper.read_text().replace("origin: [0.5, 0.0, 0.0]", "origin: [0.0, 0.0, 0.0]"))
    Image.fromarray(np.full((100, 160), 254, dtype=np.uint8)).save(directory / "upper" / "map.png")
    _refused(lambda: load_building(directory), upper, "image", "8 x 6 m", "8 x 5 m")


@pytest.mark.parametrize(
    ("storey", "center", "words"),
    [("ground", [3.0, 0.6], ("on the stairs",)), ("upper", [3.0, 1.0], ("over a stairwell",))],
)
def test_an_object_on_the_stairs_or_over_the_stairwell(
    tmp_path: Path, storey: str, center: list[float], words: tuple[str, ...]
) -> None:
    directory = _building_dir(tmp_path)
    objects = directory / storey / "objects.json"
    table = {"category": "table", "center": [4.0, 4.0], "size": [1.0, 0.6, 0.7]}
    box = {"category": "box", "center": center, "size": [0.4, 0.4, 0.4]}
    objects.write_text(json.dumps({"objects": [table, box]}))
    _refused(lambda: load_building(directory), objects, "objects[1]", *words)


# -------------------------------------------------------------------------------------------- episode checks


def _episodes(count: int = 2) -> list[dict[str, Any]]:
    library = SceneLibrary(str(BUILDINGS))
    return [episode_to_dict(e) for e in generate_episodes(library, count, 0, SIM, Storeys(1.0))]


def _write(path: Path, episodes: list[dict[str, Any]]) -> Path:
    path.write_bytes(gzip.compress(json.dumps({"episodes": episodes}).encode()))
    return path


def _validate(tmp_path: Path, episodes: list[dict[str, Any]]) -> None:
    path = _write(tmp_path / "eps.json.gz", episodes)
    validate_for_scenes(load_episodes(path), SceneLibrary(str(BUILDINGS)), path, SIM)


def test_generated_episodes_in_a_building_are_valid(tmp_path: Path) -> None:
    _validate(tmp_path, _episodes())


def test_a_start_in_the_stairwell(tmp_path: Path) -> None:
    episode = _episodes(1)[0]
    episode["start_position"] = list(world_to_habitat(3.0, 0.6, 3.0))  # upstairs, where the floor is open
    path = tmp_path / "eps.json.gz"
    words = ("a navigable position", "stairwell", "storey 1")
    _refused(lambda: _validate(tmp_path, [episode]), path, "episodes[0].start_position", *words)


def test_a_start_off_the_floor_elsewhere_is_not_called_a_stairwell(tmp_path: Path) -> None:
    episode = _episodes(1)[0]
    episode["start_position"] = list(world_to_habitat(7.0, 5.0, 1.5))  # in the air of the ground floor
    error = _refused(lambda: _validate(tmp_path, [episode]), tmp_path / "eps.json.gz", "episodes[0].start_position")
    assert "stairwell" not in str(error)


def test_a_goal_without_a_view_point_on_its_floor(tmp_path: Path) -> None:
    episode = _episodes(1)[0]
    goal = episode["goals"][0]
    floor = goal["view_points"][0]["agent_state"]["position"][1]
    other = 3.0 if floor == 0.0 else 0.0
    goal["position"][1] = other + 1.0  # the object one storey up (or down) from its view points
    words = (f"storey {int(other / 3.0)}", f"height {other:g} m", f"[{float(floor)}]")
    _refused(
        lambda: _validate(tmp_path, [episode]), tmp_path / "eps.json.gz", "episodes[0].goals[0].view_points", *words
    )


# ------------------------------------------------------------------------------------------- the command line


def _one_line_exit_2(capsys: pytest.CaptureFixture[str], args: list[str], *words: str) -> None:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d["storeys"][1].update(elevation=2.0), "'storeys[1].elevation'"),
        (lambda d: _flight(d).update(foot=[4.0, 0.6]), "'stairs[0].flights[0]'"),
    ],
    ids=["read", "loaded"],
)
def test_the_command_line_prints_one_line_and_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: Callable[[dict[str, Any]], object], field: str
) -> None:
    directory = _building_dir(tmp_path, change)
    args = ["eval", "--agent", "random", "--scenes", str(directory), "--episodes", "1", "--out", str(tmp_path / "r")]
    _one_line_exit_2(capsys, args, str(directory / BUILDING_FILE), field)
    assert not (tmp_path / "r" / "episodes.jsonl").exists()


def test_the_command_line_refuses_an_episode_starting_in_the_stairwell(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    episode = _episodes(1)[0]
    episode["start_position"] = list(world_to_habitat(3.0, 0.6, 3.0))
    path = _write(tmp_path / "eps.json.gz", [episode])
    args = [
        "eval",
        "--agent",
        "random",
        "--scenes",
        str(BUILDINGS),
        "--episodes",
        str(path),
        "--out",
        str(tmp_path / "r"),
    ]
    _one_line_exit_2(capsys, args, str(path), "'episodes[0].start_position'", "stairwell")
