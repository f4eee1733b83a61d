"""Scenes from real floor plans: a ROS map_server map (YAML + PGM/PNG image) and an optional ``objects.json``.

A scene directory holds one map YAML (a YAML mapping with an ``image`` key) whose image path is relative to
the YAML, and optionally ``objects.json`` beside it::

    {"objects": [{"category": str, "center": [x, y], "size": [sx, sy, sz], "yaw": rad, "elevation": m}, ...],
     "rooms": [{"name": str, "polygon": [[x, y], ...]}, ...]}

in the map frame (metres; the YAML origin is the world position of the lower-left pixel's lower-left corner,
as in ROS and :mod:`drivenav.grid`). ``yaw`` and ``elevation`` default to 0 and ``rooms`` to none. Without an
``objects`` list (no file, or a file with rooms only) objects are placed by
:func:`drivenav.envs.embedded.placement.place_objects`, seeded from the scene id (see :func:`scene_rng`). Object
``instance_id`` is 1 + the object's position in the list (0 means "no object" in semantic images).

Pixels are classified as in map_server's trinary mode, with these deliberate differences:

* Only the colour channels are averaged; an alpha channel is ignored. map_server (ROS 1 and Nav2) includes
  alpha in the mean, which turns the grey 205 "unknown" of an opaque RGBA image into free space (uos_cic).
* The origin yaw is ignored, as map_server and costmaps do.
* ``scale`` mode uses the trinary thresholds (intermediate values are only costs); ``raw`` mode reads the
  (channel-mean) grey level as occupancy 0..100, values above 100 (255 = -1) meaning unknown, as Nav2 does.
* 16-bit images (Pillow modes ``I;16*`` and ``I`` holding 0..65535) are scaled to 0..255 first.

Occupied pixels become :attr:`Material.WALL`, unknown pixels :attr:`Material.UNKNOWN` (sensor-opaque); neither
is navigable. The map is resampled to the scene resolution keeping its origin and covering its extent (see
:func:`resample_structure`), and free cells on the grid border become unknown so that free space reaching the
image edge (mit_building_31, uos_avz5floor_plan) cannot lead the agent off the map.
"""

from __future__ import annotations

import json
import math
import zlib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from drivenav.envs.embedded import placement
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.errors import InputError
from drivenav.grid import GridSpec
from drivenav.validation import Fields, read_json, read_yaml

OBJECTS_FILE = "objects.json"
PACKAGED_MAPS = "data/maps"  # under the drivenav package
MAP_MODES = ("trinary", "scale", "raw")
IMAGE_MODES = ("1", "L", "LA", "P", "RGB", "RGBA", "I;16", "I;16L", "I;16B", "I;16N", "I")
"""Pillow image modes the loader accepts; any other mode (F, CMYK, PA, LAB, YCbCr, ...) is an input error."""

_YAML_SUFFIXES = (".yaml", ".yml")
_MAP_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_OBJECT_KEYS = frozenset({"category", "center", "size", "yaw", "elevation"})
_ROOM_KEYS = frozenset({"name", "polygon"})
_TOP_KEYS = frozenset({"objects", "rooms"})
_EPS = 1e-6  # tolerance, in source pixels or metres, for floating-point cell boundaries

# Resampling works on ranks ordered by precedence: a target cell takes the highest rank it overlaps.
_FREE_RANK, _UNKNOWN_RANK, _WALL_RANK = 0, 1, 2
_RANK_TO_MATERIAL = np.array([Material.FREE, Material.UNKNOWN, Material.WALL], dtype=np.uint8)
_MATERIAL_TO_RANK = np.full(256, _UNKNOWN_RANK, dtype=np.uint8)
_MATERIAL_TO_RANK[[Material.FREE, Material.WALL, Material.DOOR_FRAME]] = [_FREE_RANK, _WALL_RANK, _WALL_RANK]


@dataclass(frozen=True)
class MapYaml:
    """The validated content of a map_server YAML; ``origin`` drops the yaw (ignored, as by map_server)."""

    path: Path
    image: Path
    resolution: float
    origin: tuple[float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str = "trinary"


# ---------------------------------------------------------------------------------------------------------
# Locating maps


def packaged_maps_dir() -> Path:
    """The nine real floor plans shipped with drivenav (``drivenav/data/maps``, the ``--scenes`` part ``maps``),
    byte for byte from their sources, with ``SOURCES.md`` and each source's licence under ``LICENSES/``."""
    return Path(str(resources.files("drivenav") / PACKAGED_MAPS))


def is_map_scene_dir(path: str | Path) -> bool:
    """Whether ``path`` is a directory holding exactly one map YAML (a YAML mapping with an ``image`` key)."""
    path = Path(path)
    return path.is_dir() and len(_map_yamls(path)[0]) == 1


def find_map_yaml(path: str | Path) -> Path:
    """The map YAML of a scene given as its directory or as the YAML file itself."""
    path = Path(path)
    if path.is_file():
        return path
    if not path.is_dir():
        raise InputError(path, "path", "a scene directory or a map YAML file", "nothing there")
    maps, broken = _map_yamls(path)
    if len(maps) == 1:
        return maps[0]
    if not maps and broken:
        raise broken[0]
    got = "none" if not maps else ", ".join(p.name for p in maps)
    raise InputError(path, "map yaml", "exactly one map YAML (a .yaml with an 'image' key) in the directory", got)


def _map_yamls(directory: Path) -> tuple[list[Path], list[InputError]]:
    """The directory's map YAMLs, and the errors of the YAML files that could not be parsed."""
    maps: list[Path] = []
    broken: list[InputError] = []
    for candidate in sorted(p for p in directory.iterdir() if p.suffix.lower() in _YAML_SUFFIXES):
        try:
            document = read_yaml(candidate)
        except InputError as error:
            broken.append(error)
            continue
        if isinstance(document, dict) and "image" in document:
            maps.append(candidate)
    return maps, broken


# ---------------------------------------------------------------------------------------------------------
# The map YAML


def read_map_yaml(path: str | Path) -> MapYaml:
    """Read and validate a map_server YAML (keys as in ROS map_server; ``mode`` optional, default trinary)."""
    path = Path(path)
    fields = Fields(path)
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise fields.error("", "a YAML mapping of map_server keys", type(doc).__name__)
    fields.mapping(doc, "", required=_MAP_KEYS)
    image = fields.text(doc["image"], "image")
    resolution = fields.number(doc["resolution"], "resolution", positive=True)
    origin = fields.numbers(doc["origin"], "origin", 3, "a list of 3 numbers [x, y, yaw]")
    negate = fields.choice(doc["negate"], "negate", (0, 1))  # also admits True / False
    occupied = fields.number(doc["occupied_thresh"], "occupied_thresh", minimum=0.0, maximum=1.0)
    free = fields.number(doc["free_thresh"], "free_thresh", minimum=0.0, maximum=1.0)
    if free >= occupied:
        raise fields.error("free_thresh", f"a value below occupied_thresh ({occupied})", free)
    mode = fields.choice(doc.get("mode", "trinary"), "mode", MAP_MODES)
    return MapYaml(path, path.parent / image, resolution, (origin[0], origin[1]), bool(negate), occupied, free, mode)


# ---------------------------------------------------------------------------------------------------------
# Image to occupancy


def _read_levels(meta: MapYaml) -> tuple[NDArray[np.integer[Any]], float]:
    """Integer grey levels (channel sums for colour) and the factor turning them into 0..255 values."""
    if not meta.image.is_file():
        raise InputError(meta.path, "image", "an existing image file (path relative to the YAML)", str(meta.image))
    try:
        with Image.open(meta.image) as img:
            img.load()
            if img.mode not in IMAGE_MODES:
                raise InputError(
                    meta.image, "image mode", f"one of the Pillow modes {', '.join(IMAGE_MODES)}", img.mode
                )
            converted = img.convert("RGBA") if img.mode == "P" else img.convert("L") if img.mode == "1" else img
            pixels = np.asarray(converted)
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(meta.image, "image", "a readable PGM or PNG image", str(exc)) from exc
    if pixels.ndim == 3 and pixels.shape[2] >= 3:  # RGB, RGBA, P: average the colour channels, ignore alpha
        return pixels[..., :3].sum(axis=-1, dtype=np.uint16), 1.0 / 3.0
    grey = pixels[..., 0] if pixels.ndim == 3 else pixels  # LA: drop alpha
    if grey.dtype == np.uint8:
        return grey, 1.0
    if grey.size and (int(grey.min()) < 0 or int(grey.max()) > 65535):
        raise InputError(
            meta.image, "pixel values", "16-bit grey levels in 0..65535", (int(grey.min()), int(grey.max()))
        )
    return grey.astype(np.uint16), 255.0 / 65535.0


def classify_values(values: NDArray[np.float64], meta: MapYaml) -> NDArray[np.uint8]:
    """Materials of pixels with 0..255 (channel-mean) ``values`` under the YAML's mode and thresholds."""
    if meta.mode == "raw":
        occupied = (values > meta.occupied_thresh * 100.0) & (values <= 100.0)
        free = values < meta.free_thresh * 100.0
    else:
        occ = values / 255.0 if meta.negate else (255.0 - values) / 255.0
        occupied = occ > meta.occupied_thresh
        free = occ < meta.free_thresh
    return np.where(occupied, Material.WALL, np.where(free, Material.FREE, Material.UNKNOWN)).astype(np.uint8)


def read_map_image(meta: MapYaml) -> NDArray[np.uint8]:
    """The map's materials at its own resolution, flipped so that row 0 is the lowest ``y`` (image bottom)."""
    levels, scale = _read_levels(meta)
    table = classify_values(np.arange(int(levels.max(initial=0)) + 1, dtype=np.float64) * scale, meta)
    return np.ascontiguousarray(table[levels][::-1])


# ---------------------------------------------------------------------------------------------------------
# Resampling


def resample_structure(structure: NDArray[np.uint8], source_resolution: float, resolution: float) -> NDArray[np.uint8]:
    """Resample a material grid to ``resolution``, keeping its origin and covering its whole extent.

    A target cell is a wall if any source cell it overlaps (with positive area) is a wall or door frame, else
    unknown if any is unknown or it reaches past the source extent, else free. For coarser sources with an
    integer ratio this is nearest-neighbour; for finer or non-integer ratios thin walls survive.
    """
    ratio = resolution / source_resolution  # source cells per target cell
    ranks = np.pad(_MATERIAL_TO_RANK[structure], ((0, 1), (0, 1)), constant_values=_UNKNOWN_RANK)
    for axis, n_source in enumerate(structure.shape):
        n_target = math.ceil(n_source / ratio - _EPS)
        ranks = _max_over_overlaps(ranks, axis, n_target, ratio, n_source)
    materials: NDArray[np.uint8] = _RANK_TO_MATERIAL[ranks]
    return materials


def _max_over_overlaps(
    ranks: NDArray[np.uint8], axis: int, n_target: int, ratio: float, n_source: int
) -> NDArray[np.uint8]:
    """Along ``axis``, the maximum over the source cells overlapping each target cell (index ``n_source`` is
    the padding beyond the source)."""
    j = np.arange(n_target)
    lo = np.minimum(np.floor(j * ratio + _EPS).astype(np.intp), n_source)
    hi = np.clip(np.ceil((j + 1) * ratio - _EPS).astype(np.intp) - 1, lo, n_source)
    out: NDArray[np.uint8] = np.take(ranks, lo, axis=axis)
    for k in range(1, int((hi - lo).max(initial=0)) + 1):
        out = np.maximum(out, np.take(ranks, np.minimum(lo + k, hi), axis=axis))
    return out


def _close_border(structure: NDArray[np.uint8]) -> None:
    """Turn free cells on the grid border into unknown ones, in place."""
    for edge in (structure[0], structure[-1], structure[:, 0], structure[:, -1]):
        edge[edge == Material.FREE] = Material.UNKNOWN


MAX_GRID_BYTES = 2 * 1024**3  # a scene's grids together: about eight bytes per cell


def _check_grid_size(meta: MapYaml, shape: tuple[int, ...], resolution: float) -> None:
    """Refuse, before allocating, a map whose grid at ``resolution`` would need more than 2 GiB."""
    height_m, width_m = shape[0] * meta.resolution, shape[1] * meta.resolution
    cells = math.ceil(height_m / resolution) * math.ceil(width_m / resolution)
    if cells * 8 > MAX_GRID_BYTES:
        extent = f"{width_m:.4g} x {height_m:.4g} m, {cells * 8 / 1024**3:.1f} GiB at {resolution} m per cell"
        raise InputError(meta.path, "resolution", "a map whose grid fits in 2 GiB (metres per pixel)", extent)


def load_structure(path: str | Path, resolution: float = 0.05) -> tuple[GridSpec, NDArray[np.uint8]]:
    """A scene's map (directory or YAML) as a grid and its materials at ``resolution`` metres per cell."""
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise ValueError(f"resolution must be a positive number of metres, got {resolution!r}")
    meta = read_map_yaml(find_map_yaml(path))
    image = read_map_image(meta)
    _check_grid_size(meta, image.shape, resolution)
    structure = resample_structure(image, meta.resolution, resolution)
    _close_border(structure)
    return GridSpec(resolution, meta.origin, (structure.shape[0], structure.shape[1])), structure


# ---------------------------------------------------------------------------------------------------------
# objects.json


def _inside(grid: GridSpec, x: float, y: float) -> bool:
    xmin, xmax, ymin, ymax = grid.extent
    return xmin - _EPS <= x <= xmax + _EPS and ymin - _EPS <= y <= ymax + _EPS


def _extent_text(grid: GridSpec) -> str:
    xmin, xmax, ymin, ymax = grid.extent
    return f"x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}]"


def _read_object(
    value: Any, index: int, fields: Fields, grid: GridSpec, structure: NDArray[np.uint8]
) -> ObjectInstance:
    field = f"objects[{index}]"
    entry = fields.mapping(value, field, _OBJECT_KEYS, ("category", "center", "size"))
    center = fields.numbers(entry["center"], f"{field}.center", 2, "a list of 2 numbers [x, y]")
    size = fields.numbers(entry["size"], f"{field}.size", 3, "a list of 3 positive numbers [sx, sy, sz]", positive=True)
    elevation = fields.number(entry.get("elevation", 0.0), f"{field}.elevation", minimum=0.0)
    obj = ObjectInstance(
        instance_id=index + 1,
        category=fields.text(entry["category"], f"{field}.category"),
        center=(center[0], center[1]),
        size=(size[0], size[1], size[2]),
        yaw=fields.number(entry.get("yaw", 0.0), f"{field}.yaw"),
        elevation=elevation,
    )
    cell = grid.world_to_cell(obj.center)
    if not grid.contains(cell):
        raise fields.error(f"{field}.center", f"a point on the map ({_extent_text(grid)})", entry["center"])
    material = Material(int(structure[cell[0], cell[1]]))
    if material != Material.FREE:
        name = material.name.lower()
        got = f"{list(obj.center)} inside {'an' if name[0] in 'aeiou' else 'a'} {name} cell"
        raise fields.error(f"{field}.center", "a point in free space, not inside a wall or unknown cell", got)
    if not all(_inside(grid, x, y) for x, y in obj.footprint()):
        raise fields.error(field, f"a footprint within the map ({_extent_text(grid)})", "footprint off the map")
    return obj


def _read_room(value: Any, index: int, fields: Fields, grid: GridSpec) -> Room:
    field = f"rooms[{index}]"
    entry = fields.mapping(value, field, _ROOM_KEYS, ("name", "polygon"))
    name = fields.text(entry["name"], f"{field}.name")
    polygon = fields.sequence(entry["polygon"], f"{field}.polygon", 3, "a list of at least 3 points [x, y]")
    points: list[tuple[float, float]] = []
    for k, point in enumerate(polygon):
        x, y = fields.numbers(point, f"{field}.polygon[{k}]", 2, "a point [x, y]")
        if not _inside(grid, x, y):
            raise fields.error(f"{field}.polygon[{k}]", f"a point on the map ({_extent_text(grid)})", point)
        points.append((x, y))
    return Room(name, tuple(points))


def read_objects_json(
    path: str | Path, grid: GridSpec, structure: NDArray[np.uint8]
) -> tuple[list[ObjectInstance] | None, list[Room]]:
    """Objects and rooms of a map's ``objects.json``; objects are None when the file has no ``objects`` key.

    Every object centre must lie in a free cell of ``structure`` and every footprint corner and room vertex
    within the map's extent.
    """
    path = Path(path)
    fields = Fields(path)
    doc = fields.mapping(read_json(path), "", _TOP_KEYS)
    rooms = [_read_room(v, k, fields, grid) for k, v in enumerate(fields.sequence(doc.get("rooms", []), "rooms"))]
    if "objects" not in doc:
        return None, rooms
    objects = fields.sequence(doc["objects"], "objects")
    return [_read_object(v, k, fields, grid, structure) for k, v in enumerate(objects)], rooms


def write_objects_json(scene: Scene, path: str | Path) -> Path:
    """Write the scene's objects and rooms as ``objects.json`` (``path`` is the file or its directory).

    The schema is the one :func:`load_map_scene` reads; objects keep their list order, so a file written from
    a loaded scene reloads with the same instance ids.
    """
    path = Path(path)
    if path.is_dir():
        path = path / OBJECTS_FILE
    doc = {
        "objects": [
            {
                "category": o.category,
                "center": [float(v) for v in o.center],
                "size": [float(v) for v in o.size],
                "yaw": float(o.yaw),
                "elevation": float(o.elevation),
            }
            for o in scene.objects
        ],
        "rooms": [{"name": r.name, "polygon": [[float(x), float(y)] for x, y in r.polygon]} for r in scene.rooms],
    }
    path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------------------------
# Scenes


def scene_rng(scene_id: str, seed: int | None = None) -> np.random.Generator:
    """The object-placement generator of a scene: seeded by the CRC-32 of its id and ``seed`` (mod 2**64)."""
    crc = zlib.crc32(scene_id.encode("utf-8"))
    return np.random.default_rng(crc if seed is None else [crc, seed % 2**64])


@dataclass(frozen=True, eq=False)
class MapPlan:
    """A floor plan as its map directory gives it: the map YAML, the grid and materials at the scene resolution,
    and ``objects.json``'s objects (None where it gives none: no file, or rooms only) and rooms."""

    yaml: Path
    grid: GridSpec
    structure: NDArray[np.uint8]
    objects: list[ObjectInstance] | None
    rooms: list[Room]


def read_map_plan(path: str | Path, resolution: float = 0.05) -> MapPlan:
    """Read a map directory (or its YAML file) and the ``objects.json`` beside the YAML, placing nothing: what
    :func:`load_map_scene` builds a scene from, and a building (:mod:`drivenav.envs.embedded.building_files`) a
    storey."""
    yaml_path = find_map_yaml(path)
    grid, structure = load_structure(yaml_path, resolution)
    objects: list[ObjectInstance] | None = None
    rooms: list[Room] = []
    objects_path = yaml_path.parent / OBJECTS_FILE
    if objects_path.is_file():
        objects, rooms = read_objects_json(objects_path, grid, structure)
    return MapPlan(yaml_path, grid, structure, objects, rooms)


def load_map_scene(path: str | Path, *, resolution: float = 0.05, seed: int | None = None) -> Scene:
    """Load a scene from a map_server map directory (or its YAML file); ``scene_id`` is the directory name.

    Objects and rooms come from ``objects.json`` beside the YAML; without objects there they are placed by
    :func:`drivenav.envs.embedded.placement.place_objects` with :func:`scene_rng` ``(scene_id, seed)``.
    """
    plan = read_map_plan(path, resolution)
    scene_id = plan.yaml.resolve().parent.name
    objects = plan.objects
    if objects is None:  # placed on a separate, object-free scene so that no cached grids go stale
        bare = Scene(scene_id, plan.grid, plan.structure, rooms=list(plan.rooms), source=str(plan.yaml))
        objects = placement.place_objects(bare, scene_rng(scene_id, seed))
    return Scene(scene_id, plan.grid, plan.structure, objects=list(objects), rooms=plan.rooms, source=str(plan.yaml))
