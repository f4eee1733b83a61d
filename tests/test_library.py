"""Scene sets from ``--scenes SPEC``: single parts, comma-separated mixes, and errors naming the bad part."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from drivenav.envs.embedded.library import SceneLibrary, procedural_scene_id
from drivenav.envs.embedded.rosmap import is_map_scene_dir
from drivenav.errors import InputError


def _map_names(maps_dir: Path) -> list[str]:
    return sorted(child.name for child in maps_dir.iterdir() if is_map_scene_dir(child))


def test_single_procedural_part_is_unchanged() -> None:
    library = SceneLibrary("procedural:3", seed=1)
    assert library.scene_ids == [procedural_scene_id(1000 + k) for k in range(3)]
    assert "procedural/house_01002" in library
    assert "ipa_office" not in library


def test_mixed_spec_lists_every_part_in_order(maps_dir: Path) -> None:
    houses = [procedural_scene_id(2000 + k) for k in range(2)]
    mixed = SceneLibrary(f"procedural:2,{maps_dir}", seed=2)
    assert mixed.scene_ids == houses + _map_names(maps_dir)
    reversed_parts = SceneLibrary(f"{maps_dir}, procedural:2", seed=2)
    assert reversed_parts.scene_ids == _map_names(maps_dir) + houses
    assert houses[0] in mixed and "ipa_office" in mixed
    assert mixed.load("mit_building_31").objects
    assert mixed.load(houses[1]).objects


def test_repeated_parts_add_no_duplicates(maps_dir: Path) -> None:
    library = SceneLibrary(f"procedural:2,procedural:3,{maps_dir / 'uos_cic'},{maps_dir}", seed=0)
    others = [name for name in _map_names(maps_dir) if name != "uos_cic"]
    assert library.scene_ids == [procedural_scene_id(k) for k in range(3)] + ["uos_cic", *others]


@pytest.mark.parametrize("part", ["nowhere/at/all", "procedural:0", "procedural:x", ""])
def test_an_unknown_part_names_scenes_and_the_part(part: str) -> None:
    with pytest.raises(InputError) as caught:
        SceneLibrary(f"procedural:1,{part}")
    assert caught.value.field == "--scenes"
    assert part in str(caught.value)


@pytest.mark.parametrize("part", ["homes:\u00b2", "procedural:\u0663", "homes:+3", "homes: 3"])
def test_a_scene_count_in_other_digits_is_refused(part: str) -> None:
    """``str.isdigit`` holds for '²' (and Arabic-Indic digits), which ``int`` then refused with a traceback."""
    with pytest.raises(InputError) as caught:
        SceneLibrary(part)
    assert caught.value.field == "--scenes" and part in str(caught.value) and "K from 1 to 1000" in str(caught.value)


@pytest.mark.parametrize(
    "part", ["homes:1000000000", "procedural:10000000", "procedural:1001", "homes:0001001", "homes:" + "9" * 5000]
)
def test_a_scene_count_past_one_seeds_scenes_is_refused_at_once(part: str) -> None:
    """``homes:1000000000`` ran out of memory after 42 s and ``procedural:10000000`` did not end; K scenes of seed S
    are seeds 1000 S .. 1000 S + K - 1, so K > 1000 would reach the next seed's scenes."""
    with pytest.raises(InputError, match="K from 1 to 1000") as caught:
        SceneLibrary(part, seed=3)
    assert part[:60] in str(caught.value)  # a long one is shortened
    assert len(SceneLibrary("procedural:1000", seed=3).scene_ids) == 1000  # the largest K is still a scene set
    assert len(SceneLibrary("homes:00008").scene_ids) == 8


def test_two_scenes_with_one_name_are_refused(maps_dir: Path, tmp_path: Path) -> None:
    for folder in ("a", "b"):
        shutil.copytree(maps_dir / "mit_building_31", tmp_path / folder / "mit_building_31")
    with pytest.raises(InputError, match="distinct names"):
        SceneLibrary(f"{tmp_path / 'a'},{tmp_path / 'b'}")


def test_maps_part_names_the_packaged_floor_plans_by_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # wherever the command runs, with no folder of that name there
    library = SceneLibrary("procedural:1,maps")
    plans = library.scene_ids[1:]
    assert plans == sorted(plans) and len(plans) == 9 and "uos_avz" in plans
    assert library.load("aws_small_house").scene_id == "aws_small_house"
    (tmp_path / "maps").mkdir()  # a folder of one's own named maps is ./maps
    with pytest.raises(InputError, match="no map found"):
        SceneLibrary("./maps")


def test_packaged_floor_plans_ship_their_sources_and_licences(maps_dir: Path) -> None:
    assert (maps_dir / "SOURCES.md").is_file()
    licences = {path.name for path in (maps_dir / "LICENSES").iterdir()}
    for spdx in ("BSD-3-Clause", "MIT-racecar", "MIT-0", "Apache-2.0"):
        assert any(name.startswith(spdx) for name in licences), spdx
    assert all(is_map_scene_dir(maps_dir / name) for name in SceneLibrary("maps").scene_ids)
