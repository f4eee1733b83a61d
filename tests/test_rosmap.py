"""Tests for the ROS map_server scene loader and objects.json (drivenav.envs.embedded.rosmap)."""

from __future__ import annotations

import json
import math
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from PIL import Image
from scipy import ndimage

from drivenav.envs.embedded import placement
from drivenav.envs.embedded.rosmap import (
    find_map_yaml,
    is_map_scene_dir,
    load_map_scene,
    load_structure,
    packaged_maps_dir,
    read_map_image,
    read_map_yaml,
    read_objects_json,
    resample_structure,
    scene_rng,
    write_objects_json,
)
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.errors import InputError
from drivenav.grid import GridSpec
from drivenav.types import SimConfig

F, W, U = int(Material.FREE), int(Material.WALL), int(Material.UNKNOWN)

# ------------------------ helpers


def yaml_text(**overrides: Any) -> str:
    """A map YAML with ROS defaults; an override of None drops the key."""
    keys: dict[str, Any] = {
        "image": "map.pgm",
        "resolution": 0.05,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    keys.update(overrides)
    return "".join(f"{k}: {json.dumps(v)}\n" for k, v in keys.items() if v is not None)


def write_map(
    directory: Path, image: NDArray[Any] | Image.Image, image_name: str = "map.pgm", **yaml_keys: Any
) -> Path:
    """Write a scene directory with ``map.yaml`` and its image (arrays are 8-bit grey, top row first)."""
    directory.mkdir(parents=True, exist_ok=True)
    img = image if isinstance(image, Image.Image) else Image.fromarray(np.asarray(image, dtype=np.uint8))
    img.save(directory / image_name)
    (directory / "map.yaml").write_text(yaml_text(image=image_name, **yaml_keys))
    return directory


def classified(directory: Path) -> NDArray[np.uint8]:
    """Materials at the map's own resolution (no resampling, no border closing)."""
    return read_map_image(read_map_yaml(directory / "map.yaml"))


def no_placement(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(placement, "place_objects", lambda scene, rng, density=1.0: [])


def input_error(call: Any, *args: Any) -> InputError:
    with pytest.raises(InputError) as info:
        call(*args)
    assert "\n" not in str(info.value)
    return info.value


# The grey levels below, top image row first, and their materials under the ROS defaults (0.65 / 0.196):
# occ = (255 - p) / 255: 0 -> 1.0 wall, 254 -> 0.004 free, 205 -> 0.19608 unknown, 89 -> 0.65098 wall,
# 100 -> 0.608 unknown, 255 -> 0 free, 166 -> 0.349 unknown, 90 -> 0.647 unknown.
GREY = np.array([[0, 254, 205, 89], [100, 255, 166, 90]], dtype=np.uint8)


# ------------------------ thresholds


def test_trinary_thresholds_and_row_flip(tmp_path: Path) -> None:
    got = classified(write_map(tmp_path, GREY))
    # row 0 is the bottom image row (lowest y)
    np.testing.assert_array_equal(got, [[U, F, U, U], [W, F, U, W]])


def test_negate_inverts_occupancy(tmp_path: Path) -> None:
    got = classified(write_map(tmp_path, GREY, negate=1))
    # occ = p / 255: 100 -> 0.39, 255 -> 1, 166 -> 0.651, 90 -> 0.353; 0 -> 0, 254 -> 0.996, 205 -> 0.8
    np.testing.assert_array_equal(got, [[U, W, W, U], [F, W, W, U]])


def test_scale_mode_uses_trinary_thresholds(tmp_path: Path) -> None:
    np.testing.assert_array_equal(
        classified(write_map(tmp_path / "a", GREY, mode="scale")), classified(write_map(tmp_path / "b", GREY))
    )


def test_raw_mode_reads_occupancy_percent(tmp_path: Path) -> None:
    raw = np.array([[0, 19, 20, 50, 65, 66, 100, 101, 255]], dtype=np.uint8)
    got = classified(write_map(tmp_path, raw, mode="raw", negate=1))  # negate has no effect in raw mode
    np.testing.assert_array_equal(got, [[F, F, U, U, U, W, W, U, U]])


def test_colour_channels_are_averaged_and_alpha_ignored(tmp_path: Path) -> None:
    rgba = np.array(
        [
            [[0, 255, 255, 255], [255, 255, 252, 255], [0, 0, 255, 255]],  # means 170, 254, 85
            [[205, 205, 205, 255], [0, 0, 0, 0], [254, 254, 254, 0]],  # alpha must not matter
        ],
        dtype=np.uint8,
    )
    got = classified(write_map(tmp_path, Image.fromarray(rgba), "map.png"))
    # occ(170) = 0.333 unknown, occ(254) free, occ(85) = 0.667 wall; grey 205 stays unknown (map_server: free)
    np.testing.assert_array_equal(got, [[U, W, F], [U, F, W]])


# ------------------------ image modes

BASE = np.array([[0, 205, 254], [254, 0, 205]], dtype=np.uint8)
BASE_MATERIALS = [[F, W, U], [W, U, F]]


def _as_mode(mode: str) -> Image.Image:
    grey = Image.fromarray(BASE)
    if mode == "L":
        return grey
    if mode == "LA":
        return Image.merge("LA", (grey, Image.new("L", grey.size, 7)))
    if mode in ("RGB", "RGBA", "P"):
        rgb = grey.convert("RGB")
        return rgb.convert("P", palette=Image.Palette.ADAPTIVE) if mode == "P" else rgb.convert(mode)
    wide = BASE.astype(np.uint32) * 257
    if mode == "I;16":
        return Image.fromarray(wide.astype(np.uint16))
    return Image.fromarray(wide.astype(np.int32))


@pytest.mark.parametrize(
    ("mode", "suffix"),
    [
        ("L", "png"),
        ("LA", "png"),
        ("P", "png"),
        ("RGB", "png"),
        ("RGBA", "png"),
        ("I;16", "png"),
        ("I", "pgm"),
        ("I", "tiff"),
    ],
)
def test_supported_image_modes_agree(tmp_path: Path, mode: str, suffix: str) -> None:
    directory = write_map(tmp_path, _as_mode(mode), f"map.{suffix}")
    assert Image.open(directory / f"map.{suffix}").mode.startswith(mode[0])
    np.testing.assert_array_equal(classified(directory), BASE_MATERIALS)


def test_bilevel_image(tmp_path: Path) -> None:
    bits = Image.fromarray(np.array([[0, 255], [255, 0]], dtype=np.uint8)).convert("1")
    np.testing.assert_array_equal(classified(write_map(tmp_path, bits, "map.png")), [[F, W], [W, F]])


@pytest.mark.parametrize("mode", ["F", "CMYK", "PA", "LAB", "YCbCr"])
def test_unsupported_image_modes_fail(tmp_path: Path, mode: str) -> None:
    directory = write_map(tmp_path, Image.new(mode, (4, 3)), "map.tiff")
    error = input_error(load_structure, directory)
    assert (error.field, error.got, Path(error.source).name) == ("image mode", mode, "map.tiff")


def test_32_bit_values_beyond_16_bits_fail(tmp_path: Path) -> None:
    directory = write_map(tmp_path, Image.fromarray(np.full((3, 3), 70000, np.int32)), "map.tiff")
    assert input_error(load_structure, directory).field == "pixel values"


@pytest.mark.parametrize("content", [b"not an image at all", b"P5\n4 4\n255\n\x00\x00"])
def test_corrupt_image_fails(tmp_path: Path, content: bytes) -> None:
    write_map(tmp_path, GREY)
    (tmp_path / "map.pgm").write_bytes(content)
    error = input_error(load_structure, tmp_path)
    assert error.field == "image" and "map.pgm" in str(error)


def test_truncated_png_fails(tmp_path: Path) -> None:
    write_map(tmp_path, Image.fromarray(np.random.default_rng(0).integers(0, 255, (64, 64), np.uint8)), "map.png")
    data = (tmp_path / "map.png").read_bytes()
    (tmp_path / "map.png").write_bytes(data[: len(data) // 2])
    assert input_error(load_structure, tmp_path).field == "image"


# ------------------------ resampling


def test_coarse_source_is_nearest_neighbour() -> None:
    src = np.array([[F, W, U], [U, F, W]], dtype=np.uint8)
    np.testing.assert_array_equal(resample_structure(src, 0.1, 0.05), np.kron(src, np.ones((2, 2), np.uint8)))


def test_fine_source_keeps_thin_walls_and_ranks_wall_over_unknown() -> None:
    src = np.full((4, 6), F, dtype=np.uint8)
    src[:, 3] = W  # a 1-px wall on an odd column
    src[0, 0] = U
    src[1, 2] = U  # shares a target cell with the wall
    got = resample_structure(src, 0.025, 0.05)
    np.testing.assert_array_equal(got, [[U, W, F], [F, W, F]])


def test_partial_last_cell_reaching_past_the_source_is_unknown() -> None:
    got = resample_structure(np.full((3, 3), F, np.uint8), 0.045, 0.05)  # 0.135 m -> 3 cells, last partial
    np.testing.assert_array_equal(got, [[F, F, U], [F, F, U], [U, U, U]])


def reference_resample(src: NDArray[np.uint8], rs: float, rt: float) -> NDArray[np.uint8]:
    """Brute force: interval overlaps in metres, cell by cell."""
    tol = 1e-9
    shape = tuple(math.ceil(n * rs / rt - 1e-9) for n in src.shape)
    out = np.empty(shape, np.uint8)
    for i in range(shape[0]):
        for j in range(shape[1]):
            y0, y1, x0, x1 = i * rt, (i + 1) * rt, j * rt, (j + 1) * rt
            rows = [a for a in range(src.shape[0]) if min(y1, (a + 1) * rs) - max(y0, a * rs) > tol]
            cols = [b for b in range(src.shape[1]) if min(x1, (b + 1) * rs) - max(x0, b * rs) > tol]
            values = set(src[np.ix_(rows, cols)].ravel().tolist())
            beyond = y1 > src.shape[0] * rs + tol or x1 > src.shape[1] * rs + tol
            out[i, j] = W if W in values else U if (U in values or beyond) else F
    return out


@settings(max_examples=60, deadline=None)
@given(
    grid=st.integers(1, 9).flatmap(
        lambda rows: st.integers(1, 9).flatmap(
            lambda cols: st.lists(st.sampled_from([F, F, F, W, U]), min_size=rows * cols, max_size=rows * cols).map(
                lambda v: np.array(v, np.uint8).reshape(rows, cols)
            )
        )
    ),
    rs=st.one_of(st.sampled_from([0.025, 0.045, 0.0504, 0.05, 0.1]), st.integers(150, 1500).map(lambda k: k / 1e4)),
)
def test_resample_matches_brute_force_overlaps(grid: NDArray[np.uint8], rs: float) -> None:
    np.testing.assert_array_equal(resample_structure(grid, rs, 0.05), reference_resample(grid, rs, 0.05))


@pytest.mark.parametrize("source_resolution", [0.025, 0.045, 0.0504, 0.1])
def test_load_keeps_origin_and_covers_extent(tmp_path: Path, source_resolution: float) -> None:
    directory = write_map(tmp_path, np.full((37, 53), 254), resolution=source_resolution, origin=[-3.5, 2.25, 0.0])
    grid, structure = load_structure(directory)
    assert grid.origin == (-3.5, 2.25) and grid.resolution == 0.05
    xmin, xmax, ymin, ymax = grid.extent
    width, height = 53 * source_resolution, 37 * source_resolution
    assert 0.0 <= xmax - (xmin + width) < 0.05 and 0.0 <= ymax - (ymin + height) < 0.05
    assert structure.shape == grid.shape


# ------------------------ scene geometry


def test_border_free_cells_become_unknown(tmp_path: Path) -> None:
    grid, structure = load_structure(write_map(tmp_path, np.full((10, 12), 254)))
    border = np.ones(structure.shape, bool)
    border[1:-1, 1:-1] = False
    assert (structure[border] == U).all() and (structure[~border] == F).all()
    scene = Scene("s", grid, structure)
    assert not scene.navigable_grid(0.01, 0.88)[border].any()


def test_origin_yaw_is_ignored(tmp_path: Path) -> None:
    image = np.full((20, 30), 254)
    image[5, :] = 0
    a = load_structure(write_map(tmp_path / "a", image, origin=[1.0, 2.0, 0.0]))
    b = load_structure(write_map(tmp_path / "b", image, origin=[1.0, 2.0, 3.14]))
    assert a[0] == b[0]
    np.testing.assert_array_equal(a[1], b[1])


def test_wall_lands_at_its_world_position(tmp_path: Path) -> None:
    image = np.full((40, 60), 254)
    image[9, :] = 0  # 10th image row from the top of 40 rows at 0.1 m: y in [o + 3.0, o + 3.1)
    grid, structure = load_structure(write_map(tmp_path, image, resolution=0.1, origin=[-1.0, 5.0, 0.0]))
    row, col = grid.world_to_cell([0.0, 5.0 + 3.05])
    assert structure[row, col] == W and structure[row - 2, col] == F and structure[row + 2, col] == F
    assert np.flatnonzero((structure == W).any(axis=1)).tolist() == [60, 61]


# ------------------------ YAML errors


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("image: [unclosed\n", "<document>"),
        (yaml_text(resolution=None), "resolution"),
        (yaml_text(free_thresh=None), "free_thresh"),
        (yaml_text(resolution=-0.05), "resolution"),
        (yaml_text(resolution=0), "resolution"),
        (yaml_text(resolution="fine"), "resolution"),
        (yaml_text(resolution=True), "resolution"),
        (yaml_text(origin=[0, 0]), "origin"),
        (yaml_text(origin="0 0 0"), "origin"),
        (yaml_text(origin=[0, "a", 0]), "origin[1]"),
        (yaml_text(negate=2), "negate"),
        (yaml_text(occupied_thresh=1.5), "occupied_thresh"),
        (yaml_text(free_thresh=-0.1), "free_thresh"),
        (yaml_text(free_thresh=0.7), "free_thresh"),
        (yaml_text(free_thresh=0.65), "free_thresh"),
        (yaml_text(mode="fancy"), "mode"),
        (yaml_text(image=""), "image"),
        (yaml_text(image=5), "image"),
        (yaml_text(image="missing.pgm"), "image"),
    ],
)
def test_bad_yaml(tmp_path: Path, text: str, field: str) -> None:
    write_map(tmp_path, GREY)
    (tmp_path / "map.yaml").write_text(text)
    for path in (tmp_path, tmp_path / "map.yaml"):
        error = input_error(load_structure, path)
        assert error.field == field
        assert str(error).startswith(str(tmp_path / "map.yaml")) and f"'{field}'" in str(error)


@pytest.mark.parametrize("spelling", ["5e-2", "5.0E-2", "0.5e-1", "+.05"])
def test_yaml_12_floats_are_numbers(tmp_path: Path, spelling: str) -> None:
    """``5e-2`` is a number for yaml-cpp (ROS) and YAML 1.2, though text for YAML 1.1 (PyYAML's safe loader)."""
    write_map(tmp_path, GREY)
    (tmp_path / "map.yaml").write_text(yaml_text().replace("resolution: 0.05", f"resolution: {spelling}"))
    assert read_map_yaml(tmp_path / "map.yaml").resolution == 0.05


def test_yaml_that_is_not_a_mapping(tmp_path: Path) -> None:
    write_map(tmp_path, GREY)
    (tmp_path / "map.yaml").write_text("- a\n- b\n")
    assert input_error(load_structure, tmp_path / "map.yaml").field == "<document>"
    assert input_error(load_structure, tmp_path).field == "map yaml"  # a directory without a map YAML


def test_directory_must_hold_exactly_one_map_yaml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    no_placement(monkeypatch)
    assert input_error(load_map_scene, tmp_path / "nowhere").field == "path"
    assert input_error(load_map_scene, tmp_path).field == "map yaml"
    assert not is_map_scene_dir(tmp_path)
    write_map(tmp_path, GREY)
    (tmp_path / "params.yaml").write_text("speed: 3\n")  # not a map YAML: ignored
    assert is_map_scene_dir(tmp_path) and find_map_yaml(tmp_path) == tmp_path / "map.yaml"
    assert load_map_scene(tmp_path).scene_id == tmp_path.name
    (tmp_path / "other.yml").write_text(yaml_text())
    error = input_error(load_map_scene, tmp_path)
    assert error.field == "map yaml" and error.got == "map.yaml, other.yml"
    assert not is_map_scene_dir(tmp_path)
    assert load_map_scene(tmp_path / "other.yml").scene_id == tmp_path.name  # the YAML itself is fine


def test_directory_with_only_a_broken_yaml_reports_the_parse_error(tmp_path: Path) -> None:
    (tmp_path / "map.yaml").write_text("image: map.pgm\nresolution: [0.05\n")
    error = input_error(load_structure, tmp_path)
    assert error.field == "<document>" and "line" in str(error)


# ------------------------ objects.json

# A 2 m x 2 m map at 0.05 m with origin (-1, 2): a wall at x in [0, 0.05) and unknown x < -0.5, y >= 3.5.
ORIGIN = (-1.0, 2.0)
FREE_POINT, WALL_POINT, UNKNOWN_POINT = (-0.5, 2.5), (0.025, 2.5), (-0.8, 3.8)


def object_map(directory: Path) -> Path:
    image = np.full((40, 40), 254)
    image[:, 20] = 0
    image[:10, :10] = 205
    return write_map(directory, image, origin=[*ORIGIN, 0.0])


def good_objects() -> dict[str, Any]:
    return {
        "objects": [
            {"category": "chair", "center": [-0.5, 2.5], "size": [0.4, 0.5, 0.9], "yaw": 0.3},
            {"category": "tv", "center": [0.5, 3.0], "size": [0.1, 0.8, 0.5], "yaw": 0, "elevation": 1.2},
            {"category": "plant", "center": [0.6, 2.4], "size": [0.2, 0.2, 0.6]},
        ],
        "rooms": [{"name": "office", "polygon": [[-1, 2], [0, 2], [0, 4], [-1, 4]]}],
    }


def test_objects_json_is_loaded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(placement, "place_objects", lambda *a, **k: pytest.fail("placement must not run"))
    (object_map(tmp_path) / "objects.json").write_text(json.dumps(good_objects()))
    scene = load_map_scene(tmp_path)
    assert scene.objects == [
        ObjectInstance(1, "chair", (-0.5, 2.5), (0.4, 0.5, 0.9), 0.3, 0.0),
        ObjectInstance(2, "tv", (0.5, 3.0), (0.1, 0.8, 0.5), 0.0, 1.2),
        ObjectInstance(3, "plant", (0.6, 2.4), (0.2, 0.2, 0.6), 0.0, 0.0),
    ]
    assert scene.rooms == [Room("office", ((-1.0, 2.0), (0.0, 2.0), (0.0, 4.0), (-1.0, 4.0)))]
    row, col = scene.grid.world_to_cell(FREE_POINT)
    assert scene.room_index[row, col] == 1 and scene.source.endswith("map.yaml")


def _with(path: tuple[str | int, ...], value: Any) -> dict[str, Any]:
    doc = good_objects()
    node: Any = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return doc


def _without(section: str, index: int, key: str) -> dict[str, Any]:
    doc = good_objects()
    del doc[section][index][key]
    return doc


@pytest.mark.parametrize(
    ("content", "field", "fragment"),
    [
        ("{not json", "<document>", "valid JSON"),
        ("[]", "<document>", "JSON object"),
        (_with(("extras",), 1), "extras", "unknown key"),
        (_with(("objects",), {}), "objects", "JSON array"),
        (_with(("objects", 1), 5), "objects[1]", "JSON object"),
        (_without("objects", 0, "category"), "objects[0].category", "missing"),
        (_with(("objects", 0, "category"), 3), "objects[0].category", "non-empty string"),
        (_with(("objects", 0, "center"), [1.0]), "objects[0].center", "2 numbers"),
        (_with(("objects", 0, "center"), [math.nan, 2.5]), "objects[0].center[0]", "finite number"),
        (_with(("objects", 0, "size"), [1, 1]), "objects[0].size", "3 positive numbers"),
        (_with(("objects", 0, "size"), [0.4, 0, 1]), "objects[0].size", "3 positive numbers"),
        (_with(("objects", 2, "size"), [0.4, "a", 1]), "objects[2].size[1]", "finite number"),
        (_with(("objects", 0, "yaw"), "north"), "objects[0].yaw", "finite number"),
        (_with(("objects", 0, "elevation"), -1), "objects[0].elevation", ">= 0"),
        (_with(("objects", 0, "colour"), "red"), "objects[0].colour", "unknown key"),
        (_with(("objects", 1, "center"), [5.0, 5.0]), "objects[1].center", "on the map"),
        (_with(("objects", 0, "center"), list(WALL_POINT)), "objects[0].center", "inside a wall cell"),
        (_with(("objects", 0, "center"), list(UNKNOWN_POINT)), "objects[0].center", "inside an unknown cell"),
        (_with(("objects", 2, "size"), [3.0, 0.2, 0.6]), "objects[2]", "footprint"),
        (_with(("rooms",), "office"), "rooms", "JSON array"),
        (_without("rooms", 0, "name"), "rooms[0].name", "missing"),
        (_with(("rooms", 0, "polygon"), [[-1, 2], [0, 2]]), "rooms[0].polygon", "at least 3 points"),
        (_with(("rooms", 0, "polygon", 2), [0, 4.5]), "rooms[0].polygon[2]", "on the map"),
        (_with(("rooms", 0, "polygon", 1), [0]), "rooms[0].polygon[1]", "point [x, y]"),
    ],
)
def test_bad_objects_json(tmp_path: Path, content: str | dict[str, Any], field: str, fragment: str) -> None:
    object_map(tmp_path)
    (tmp_path / "objects.json").write_text(content if isinstance(content, str) else json.dumps(content))
    error = input_error(load_map_scene, tmp_path)
    assert error.field == field and fragment in str(error)
    assert str(error).startswith(str(tmp_path / "objects.json"))


def test_write_objects_json_round_trip(tmp_path: Path) -> None:
    (object_map(tmp_path / "a") / "objects.json").write_text(json.dumps(good_objects()))
    scene = load_map_scene(tmp_path / "a")
    object_map(tmp_path / "b")
    written = write_objects_json(scene, tmp_path / "b")
    assert written == tmp_path / "b" / "objects.json"
    again = load_map_scene(tmp_path / "b")
    assert (again.objects, again.rooms) == (scene.objects, scene.rooms)


@settings(max_examples=40, deadline=None)
@given(
    boxes=st.lists(
        st.tuples(
            st.floats(-0.9, -0.1),  # x: free strip between the map edge and the wall
            st.floats(2.1, 3.4),  # y: below the unknown block
            st.floats(0.01, 0.1),
            st.floats(0.01, 0.1),
            st.floats(0.01, 3.0),
            st.floats(-math.pi, math.pi),
            st.floats(0.0, 2.0),
            st.text(min_size=1, max_size=12).filter(str.strip),
        ),
        max_size=6,
    )
)
def test_write_then_read_preserves_objects(tmp_path_factory: pytest.TempPathFactory, boxes: list[Any]) -> None:
    grid = GridSpec(0.05, ORIGIN, (40, 40))
    structure = np.full(grid.shape, F, np.uint8)
    objects = [
        ObjectInstance(k + 1, c, (x, y), (sx, sy, sz), yaw, e) for k, (x, y, sx, sy, sz, yaw, e, c) in enumerate(boxes)
    ]
    rooms = [Room("hall", ((-1.0, 2.0), (0.7, 2.0), (0.1 / 3, 4.0)))]
    path = write_objects_json(Scene("s", grid, structure, objects, rooms), tmp_path_factory.mktemp("rt") / "o.json")
    assert read_objects_json(path, grid, structure) == (objects, rooms)


# ------------------------ placement


def _recording_placement(calls: list[tuple[Scene, float]]) -> Any:
    def fake(scene: Scene, rng: np.random.Generator, density: float = 1.0) -> list[ObjectInstance]:
        calls.append((scene, float(rng.random())))
        return [ObjectInstance(1, "chair", FREE_POINT, (0.3, 0.3, 0.8))]

    return fake


def test_objects_are_placed_with_a_scene_seeded_rng(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[Scene, float]] = []
    monkeypatch.setattr(placement, "place_objects", _recording_placement(calls))
    one, two = object_map(tmp_path / "one"), object_map(tmp_path / "two")
    scene = load_map_scene(one)
    assert [o.category for o in scene.objects] == ["chair"]
    assert calls[0][0].objects == [] and calls[0][0].scene_id == "one"
    load_map_scene(one / "map.yaml")
    load_map_scene(one, seed=7)
    load_map_scene(one, seed=7)
    load_map_scene(two)
    draws = [draw for _, draw in calls]
    assert draws[0] == draws[1] == np.random.default_rng(zlib.crc32(b"one")).random()
    assert draws[2] == draws[3] == scene_rng("one", 7).random() != draws[0]
    assert draws[4] not in (draws[0], draws[2])


def test_rooms_without_objects_are_placement_priors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[Scene, float]] = []
    monkeypatch.setattr(placement, "place_objects", _recording_placement(calls))
    doc = good_objects()
    del doc["objects"]
    (object_map(tmp_path) / "objects.json").write_text(json.dumps(doc))
    scene = load_map_scene(tmp_path)
    assert [r.name for r in calls[0][0].rooms] == ["office"] and len(scene.objects) == 1


def test_real_placement_puts_objects_in_free_space(tmp_path: Path) -> None:
    image = np.full((120, 160), 254)
    image[[0, -1], :] = image[:, [0, -1]] = 0
    image[60, :100] = 0
    try:
        scene = load_map_scene(write_map(tmp_path, image))
    except NotImplementedError:
        pytest.skip("drivenav.envs.embedded.placement.place_objects is not implemented yet")
    assert scene.objects
    cells = scene.grid.world_to_cell(np.array([o.center for o in scene.objects]))
    assert (scene.structure[cells[:, 0], cells[:, 1]] == F).all()


# ------------------------ the packaged floor plans

PACKAGED = packaged_maps_dir()
MAP_NAMES = [
    "aws_small_house",
    "ipa_apartment",
    "ipa_office",
    "mit_building_31",
    "mit_stata_basement",
    "uos_avz",
    "uos_avz5floor_plan",
    "uos_cic",
    "willow_garage",
]


@pytest.fixture(params=MAP_NAMES)
def packaged_map(request: pytest.FixtureRequest) -> Path:
    return PACKAGED / str(request.param)


def test_packaged_map_loads_with_sensible_navigable_space(packaged_map: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    no_placement(monkeypatch)
    assert is_map_scene_dir(packaged_map)
    scene = load_map_scene(packaged_map)
    assert scene.scene_id == packaged_map.name and scene.grid.resolution == 0.05
    meta = read_map_yaml(find_map_yaml(packaged_map))
    assert scene.grid.origin == meta.origin
    structure = scene.structure
    for edge in (structure[0], structure[-1], structure[:, 0], structure[:, -1]):
        assert not (edge == F).any()
    config = SimConfig()
    navigable = scene.navigable_grid(config.agent_radius, config.agent_height)
    labels, _ = ndimage.label(navigable)
    sizes = np.bincount(labels.ravel())[1:]
    cell_area = scene.grid.resolution**2
    assert navigable.sum() * cell_area > 50.0
    assert sizes.max() >= 0.8 * sizes.sum()


def test_packaged_native_resolution_map_matches_the_image(monkeypatch: pytest.MonkeyPatch) -> None:
    grey = np.asarray(Image.open(PACKAGED / "uos_avz" / "avz.pgm"), dtype=np.float64)
    occ = (255.0 - grey) / 255.0
    expected = np.where(occ > 0.65, W, np.where(occ < 0.196, F, U))
    _, structure = load_structure(PACKAGED / "uos_avz")
    np.testing.assert_array_equal(structure[::-1][1:-1, 1:-1], expected[1:-1, 1:-1])


@pytest.mark.parametrize(
    ("name", "shape"),
    [
        ("ipa_office", (699, 970)),
        ("uos_avz5floor_plan", (564, 360)),
        ("mit_stata_basement", (1311, 1744)),
        ("willow_garage", (1216, 1132)),
    ],
)
def test_packaged_resampled_map_shapes(name: str, shape: tuple[int, int]) -> None:
    assert load_structure(PACKAGED / name)[1].shape == shape


def test_packaged_rgba_map_ignores_alpha() -> None:
    _, structure = load_structure(PACKAGED / "uos_cic")
    # RGB-only: about 62 % unknown (map_server's alpha averaging would give 0.1 %)
    assert 0.55 < (structure == U).mean() < 0.7
