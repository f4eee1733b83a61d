"""The object vocabulary: size, count and consistency of the packaged categories, synonym resolution, validation."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivenav.envs.vocabulary import (
    VOCABULARY,
    PlacementStyle,
    canonical_category,
    categories,
    category_spec,
    load_vocabulary,
    normalize_term,
    synonyms,
)
from drivenav.errors import InputError

PACKAGED = Path(__file__).resolve().parents[1] / "src" / "drivenav" / "data" / "vocabulary.json"
SOFA = categories().index("sofa")


def test_at_least_100_unique_categories() -> None:
    names = categories()
    assert len(names) >= 100
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("name", ["bed", "toilet", "sofa", "chair", "armchair", "tv", "refrigerator", "sink"])
def test_core_hm3d_categories_present(name: str) -> None:
    assert name in categories()


@pytest.mark.parametrize(
    "name", ["bathtub", "shower", "plant", "fire extinguisher", "microwave", "oven", "washing machine", "desk"]
)
def test_more_core_categories_present(name: str) -> None:
    assert name in categories()


@pytest.mark.parametrize("name", ["bookshelf", "lamp", "picture", "mirror", "elevator", "vending machine"])
def test_office_and_robot_demo_categories_present(name: str) -> None:
    assert name in categories()


def test_every_spec_is_valid() -> None:
    for spec in VOCABULARY.specs:
        assert all(0.0 < lo <= hi for lo, hi in zip(spec.size_min, spec.size_max, strict=True)), spec.name
        assert max(spec.size_max) <= 5.0, spec.name  # nothing in a home is bigger than a car
        assert 0.0 <= spec.elevation[0] <= spec.elevation[1] < 2.6, spec.name  # below the ceiling
        assert spec.elevation[1] + spec.size_max[2] <= 2.6 + 1e-9, spec.name
        assert all(w >= 0.0 for _, w in spec.priors) and spec.generic_prior >= 0.0, spec.name
        assert {room for room, _ in spec.priors} <= set(VOCABULARY.room_types), spec.name
        assert spec.max_per_room >= 1
        assert sum(w for _, w in spec.priors) + spec.generic_prior > 0.0, f"{spec.name} can never be placed"
        assert (spec.style is PlacementStyle.SURFACE) == bool(spec.hosts), spec.name
        assert set(spec.hosts) <= set(categories()), spec.name


def test_furniture_stands_on_the_floor_and_wall_items_are_mounted() -> None:
    for name in ("bed", "sofa", "toilet", "refrigerator", "desk", "chair"):
        assert category_spec(name).elevation == (0.0, 0.0)
    for name in ("picture", "mirror", "fire extinguisher", "tv"):
        spec = category_spec(name)
        assert spec.style is PlacementStyle.MOUNTED
        assert spec.elevation[0] > 0.0


def test_every_room_type_and_the_generic_prior_have_candidates() -> None:
    for room in VOCABULARY.room_types:
        assert sum(spec.prior(room) for spec in VOCABULARY.specs) > 0.0, room
    assert sum(spec.prior(None) for spec in VOCABULARY.specs) > 0.0


@pytest.mark.parametrize(
    ("category", "room"),
    [
        ("bed", "bedroom"),
        ("toilet", "bathroom"),
        ("refrigerator", "kitchen"),
        ("sofa", "living room"),
        ("car", "garage"),
    ],
)
def test_priors_favour_the_typical_room(category: str, room: str) -> None:
    spec = category_spec(category)
    assert spec.prior(room) == max(spec.prior(r) for r in VOCABULARY.room_types)
    assert spec.prior(room) > 0.0


def test_unknown_room_type_has_no_weight_and_none_means_generic() -> None:
    spec = category_spec("chair")
    assert spec.prior("spaceship") == 0.0
    assert spec.prior(None) == spec.generic_prior > 0.0


def test_synonyms_are_unambiguous() -> None:
    owner: dict[str, str] = {}
    for spec in VOCABULARY.specs:
        for term in (spec.name, *spec.synonyms):
            key = normalize_term(term)
            assert owner.setdefault(key, spec.name) == spec.name, f"{term!r}: {owner[key]} and {spec.name}"


def test_every_category_has_synonyms_and_they_resolve_back() -> None:
    with_synonyms = [spec for spec in VOCABULARY.specs if spec.synonyms]
    assert len(with_synonyms) >= 0.95 * len(VOCABULARY.specs)
    for spec in VOCABULARY.specs:
        assert canonical_category(spec.name) == spec.name
        for term in spec.synonyms:
            assert canonical_category(term) == spec.name


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("Couch", "sofa"),
        ("settee", "sofa"),
        ("TV Screen", "tv"),
        ("television", "tv"),
        ("fridge", "refrigerator"),
        ("  Fire-Extinguisher ", "fire extinguisher"),
        ("washing_machine", "washing machine"),
        ("potted plant", "plant"),
        ("chairs", "chair"),
        ("benches", "bench"),
        ("spaceship", None),
        ("", None),
    ],
)
def test_canonical_category(text: str, expected: str | None) -> None:
    assert canonical_category(text) == expected


def test_synonyms_of_a_category() -> None:
    assert {"couch", "settee"} <= set(synonyms("sofa"))
    assert "fridge" in synonyms("refrigerator")
    with pytest.raises(KeyError):
        synonyms("couch")  # synonyms() takes canonical names


@given(st.sampled_from(categories()), st.integers(0, 2**32 - 1))
def test_sampled_sizes_and_elevations_lie_in_range(name: str, seed: int) -> None:
    spec = category_spec(name)
    rng = np.random.default_rng(seed)
    size = spec.sample_size(rng)
    assert all(lo <= s <= hi for s, lo, hi in zip(size, spec.size_min, spec.size_max, strict=True))
    assert spec.elevation[0] <= spec.sample_elevation(rng) <= spec.elevation[1]


def test_packaged_file_loads_identically_from_a_path() -> None:
    assert load_vocabulary(PACKAGED).categories() == categories()


def _edited(tmp_path: Path, edit: Any) -> Path:
    raw = json.loads(PACKAGED.read_text(encoding="utf-8"))
    edit(raw)
    path = tmp_path / "vocab.json"
    path.write_text(json.dumps(raw), encoding="utf-8")
    return path


def _first(raw: dict[str, Any]) -> dict[str, Any]:
    entry: dict[str, Any] = raw["categories"][0]
    return entry


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        # the second owner of a term is named, by its place in the file
        (lambda raw: _first(raw).update(synonyms=["couch"]), f"categories[{SOFA}].synonyms[0]"),
        (lambda raw: _first(raw).update(synonyms=["--"]), "categories[0].synonyms[0]"),
        (lambda raw: _first(raw).update(size_min=[1.0, -1.0, 0.5]), "categories[0].size_min"),
        (lambda raw: _first(raw).update(size_max=[0.5, 0.5, 0.5]), "categories[0].size_max"),
        (lambda raw: _first(raw).update(priors={"attic": 1.0}), "categories[0].priors.attic"),
        (lambda raw: _first(raw).update(style="floating"), "categories[0].style"),
        (lambda raw: _first(raw).update(elevation=[1.0, 0.5]), "categories[0].elevation"),
        (lambda raw: _first(raw).update(style="surface", hosts=[]), "categories[0].hosts"),
        (lambda raw: _first(raw).update(hosts=["bed", "cloud"]), "categories[0].hosts[1]"),
        (lambda raw: raw["anchors"].update(bedroom=["bed", "unicorn"]), "anchors.bedroom[1]"),
        (lambda raw: raw["anchors"].update(attic=["bed"]), "anchors.attic"),
        (lambda raw: raw["density"].update(attic=0.1), "density.attic"),
        (lambda raw: raw.update(generic_density=-1), "generic_density"),
    ],
)
def test_bad_files_name_the_field(tmp_path: Path, edit: Any, field: str) -> None:
    path = _edited(tmp_path, edit)
    with pytest.raises(InputError) as info:
        load_vocabulary(path)
    assert info.value.field == field
    assert str(info.value).startswith(f"{path}: field '{field}': expected ")


def test_invalid_json_is_an_input_error(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text("{not json", encoding="utf-8")
    with pytest.raises(InputError, match="valid JSON"):
        load_vocabulary(path)


def test_a_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="'<document>': expected a readable file"):
        load_vocabulary(tmp_path / "nowhere.json")
