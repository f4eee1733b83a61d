"""Scene sets named on the command line (``--scenes SPEC``) and loading scenes by id.

SPEC is one part or several joined by commas (``procedural:40,maps``). A part is ``procedural`` (procedural houses;
``procedural:K`` picks K houses for episode generation), ``homes`` (HM3D-like one-floor homes of
:mod:`drivenav.envs.embedded.homes`; ``homes:K`` picks K), ``storeys`` (homes of one to three storeys joined by stairs,
:mod:`drivenav.envs.embedded.storeys`; ``storeys:K`` picks K), ``maps`` (the nine real floor plans shipped with
drivenav, :func:`drivenav.envs.embedded.rosmap.packaged_maps_dir`), a scene directory (a ROS map YAML plus optional
objects.json; or a building directory, whose ``building.yaml`` stacks such floor plans and joins them by stairs,
:mod:`drivenav.envs.embedded.building_files`), or a folder of scene directories (a folder of your own named ``maps`` is
``./maps``). Generated scene ids (``procedural/house_00042``, ``homes/home_00042``, ``storeys/home_00042``) carry their
seed, so any of them can be rebuilt from the id alone; the generated parts use seeds ``1000 * S + k`` for ``--seed S``
and K scenes (8 when K is not given, at most 1000). A map scene's or building's id is its directory name (the packaged
plans' too: ``uos_avz``).
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.scene import Scene
from drivenav.errors import InputError

PROCEDURAL_ID = re.compile(r"^procedural/house_(\d+)$")
HOMES_ID = re.compile(r"^homes/home_(\d+)$")
STOREYS_ID = re.compile(r"^storeys/home_(\d+)$")
DEFAULT_PROCEDURAL_HOUSES = 8
DEFAULT_HOMES = 8  # homes in the part ``homes`` without ``:K``
SEEDS_PER_RUN_SEED = 1000  # a part's K scenes of --seed S have seeds 1000 S .. 1000 S + K - 1: K is at most this
PACKAGED_MAPS_PART = "maps"  # the SPEC part naming the floor plans shipped with drivenav


def procedural_scene_id(seed: int) -> str:
    return f"procedural/house_{seed:05d}"


def home_scene_id(seed: int) -> str:
    return f"homes/home_{seed:05d}"


def storeyed_scene_id(seed: int) -> str:
    return f"storeys/home_{seed:05d}"


@lru_cache(maxsize=8)
def _load_procedural(seed: int) -> Scene:
    from drivenav.envs.embedded.procedural import generate_house

    return generate_house(seed)


@lru_cache(maxsize=8)
def _load_home(seed: int) -> Scene:
    from drivenav.envs.embedded.homes import generate_home

    return generate_home(seed)


@lru_cache(maxsize=8)
def _load_storeyed(seed: int) -> Building:
    from drivenav.envs.embedded.storeys import generate_storeyed_home

    return generate_storeyed_home(seed)


@lru_cache(maxsize=8)
def _load_map(path: str) -> Scene:
    from drivenav.envs.embedded.rosmap import load_map_scene

    return load_map_scene(path)


@lru_cache(maxsize=8)
def _load_building(path: str) -> Building:
    from drivenav.envs.embedded.building_files import load_building

    return load_building(path)


class SceneLibrary:
    """The scenes of one ``--scenes`` SPEC: their ids (for generating episodes) and a loader by id."""

    def __init__(self, spec: str = "procedural", seed: int = 0) -> None:
        self.spec = spec
        self._maps: dict[str, Path] = {}
        self._procedural = False
        self._homes = False
        self._storeys = False
        self._order: list[str] = []
        for part in spec.split(","):
            self._add_part(part.strip(), seed)

    def _add_part(self, part: str, seed: int) -> None:
        if not part:
            raise InputError("command line", "--scenes", "comma-separated parts, none empty", self.spec)
        if part == "procedural" or part.startswith("procedural:"):
            self._procedural = True
            count = _parse_count(part, DEFAULT_PROCEDURAL_HOUSES)
            ids = [procedural_scene_id(seed * SEEDS_PER_RUN_SEED + k) for k in range(count)]
        elif part == "homes" or part.startswith("homes:"):
            self._homes = True
            ids = [home_scene_id(seed * SEEDS_PER_RUN_SEED + k) for k in range(_parse_count(part, DEFAULT_HOMES))]
        elif part == "storeys" or part.startswith("storeys:"):
            self._storeys = True
            count = _parse_count(part, DEFAULT_HOMES)
            ids = [storeyed_scene_id(seed * SEEDS_PER_RUN_SEED + k) for k in range(count)]
        else:
            maps = _find_map_dirs(part)
            for scene_id, path in maps.items():
                if self._maps.setdefault(scene_id, path) != path:
                    raise InputError(path, "--scenes", "scene directories with distinct names", scene_id)
            ids = list(maps)
        self._order.extend(i for i in ids if i not in self._order)

    @property
    def scene_ids(self) -> list[str]:
        """The scenes episodes are generated over: the SPEC's parts in order, each part's scenes in a fixed order."""
        return list(self._order)

    def __contains__(self, scene_id: str) -> bool:
        return (
            scene_id in self._maps
            or (self._procedural and PROCEDURAL_ID.match(scene_id) is not None)
            or (self._homes and HOMES_ID.match(scene_id) is not None)
            or (self._storeys and STOREYS_ID.match(scene_id) is not None)
        )

    def load(self, scene_id: str) -> Scene | Building:
        """The scene or building with this id (cached per process)."""
        if scene_id in self._maps:
            from drivenav.envs.embedded.building_files import BUILDING_FILE

            path = self._maps[scene_id]
            return _load_building(str(path)) if path.name == BUILDING_FILE else _load_map(str(path))
        match = PROCEDURAL_ID.match(scene_id)
        if match is not None and self._procedural:
            return _load_procedural(int(match.group(1)))
        match = HOMES_ID.match(scene_id)
        if match is not None and self._homes:
            return _load_home(int(match.group(1)))
        match = STOREYS_ID.match(scene_id)
        if match is not None and self._storeys:
            return _load_storeyed(int(match.group(1)))
        raise KeyError(scene_id)


def _parse_count(part: str, default: int) -> int:
    """K of a generated part (``procedural:K``, ``homes:K``), ``default`` for the bare name: decimal digits, 1 to
    :data:`SEEDS_PER_RUN_SEED` (more would reach the scenes of the next ``--seed``)."""
    name, sep, text = part.partition(":")
    if not sep:
        return default
    digits = re.fullmatch("0*([0-9]{1,4})", text)  # ASCII digits ('²' passes str.isdigit), few enough for int
    if digits is None or not 1 <= int(digits.group(1)) <= SEEDS_PER_RUN_SEED:
        expected = f"'{name}' or '{name}:K' with K from 1 to {SEEDS_PER_RUN_SEED} (the scenes of one --seed)"
        raise InputError("command line", "--scenes", expected, part)
    return int(digits.group(1))


def _find_map_dirs(part: str) -> dict[str, Path]:
    """The map scenes and buildings of one SPEC part by id, in name order: a map scene's directory (or YAML), a
    building's building.yaml."""
    from drivenav.envs.embedded.building_files import find_building_yaml, read_building_yaml
    from drivenav.envs.embedded.rosmap import find_map_yaml, is_map_scene_dir, packaged_maps_dir, read_map_yaml

    path = packaged_maps_dir() if part == PACKAGED_MAPS_PART else Path(part)
    if not path.exists():
        raise InputError(
            path, "--scenes", "'procedural', 'homes', 'maps', a scene directory, or a folder of scene directories", part
        )
    path = path.resolve()
    building = find_building_yaml(path)
    if building is not None:
        read_building_yaml(building)  # a broken building.yaml names its own file and field
        return {building.parent.name: building}
    if path.is_file() or is_map_scene_dir(path) or any(path.glob("*.yaml")):
        read_map_yaml(find_map_yaml(path))  # a broken map names its own file and field
        directory = path.parent if path.is_file() else path
        return {directory.name: path}
    found = _scenes_in_folder(path)
    if not found:
        expected = "a scene directory (map YAML + image, or building.yaml) or a folder of them"
        raise InputError(path, "--scenes", expected, "no map found")
    return found


def _scenes_in_folder(folder: Path) -> dict[str, Path]:
    """The folder's building directories (by their building.yaml, read at once so that a broken one is no scene
    silently left out) and map scene directories, by name."""
    from drivenav.envs.embedded.building_files import find_building_yaml, read_building_yaml
    from drivenav.envs.embedded.rosmap import is_map_scene_dir

    found: dict[str, Path] = {}
    for child in sorted(c for c in folder.iterdir() if c.is_dir()):
        building = find_building_yaml(child)
        if building is not None:
            read_building_yaml(building)
            found[child.name] = building
        elif is_map_scene_dir(child):
            found[child.name] = child
    return found
