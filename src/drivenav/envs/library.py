"""Scene sets named on the command line (``--scenes SPEC``) and loading scenes by id.

SPEC is ``procedural`` (procedural houses; ``procedural:K`` picks K houses for episode generation), a scene
directory (a ROS map YAML plus optional objects.json), or a folder of scene directories. Procedural scene ids
(``procedural/house_00042``) carry their seed, so any of them can be rebuilt from the id alone.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from drivenav.envs.scene import Scene
from drivenav.errors import InputError

PROCEDURAL_ID = re.compile(r"^procedural/house_(\d+)$")
DEFAULT_PROCEDURAL_HOUSES = 8


def procedural_scene_id(seed: int) -> str:
    return f"procedural/house_{seed:05d}"


@lru_cache(maxsize=8)
def _load_procedural(seed: int) -> Scene:
    from drivenav.envs.procedural import generate_house

    return generate_house(seed)


@lru_cache(maxsize=8)
def _load_map(path: str) -> Scene:
    from drivenav.envs.rosmap import load_map_scene

    return load_map_scene(path)


class SceneLibrary:
    """The scenes of one ``--scenes`` SPEC: their ids (for generating episodes) and a loader by id."""

    def __init__(self, spec: str = "procedural", seed: int = 0) -> None:
        self.spec = spec
        self._maps: dict[str, Path] = {}
        self._procedural_ids: list[str] = []
        if spec == "procedural" or spec.startswith("procedural:"):
            count = _parse_house_count(spec)
            self._procedural_ids = [procedural_scene_id(seed * 1000 + k) for k in range(count)]
        else:
            self._maps = _find_map_dirs(Path(spec))

    @property
    def scene_ids(self) -> list[str]:
        """The scenes episodes are generated over, in a fixed order."""
        return self._procedural_ids + sorted(self._maps)

    def __contains__(self, scene_id: str) -> bool:
        return scene_id in self._maps or (bool(self._procedural_ids) and PROCEDURAL_ID.match(scene_id) is not None)

    def load(self, scene_id: str) -> Scene:
        """The scene with this id (cached per process)."""
        if scene_id in self._maps:
            return _load_map(str(self._maps[scene_id]))
        match = PROCEDURAL_ID.match(scene_id)
        if match is not None and self._procedural_ids:
            return _load_procedural(int(match.group(1)))
        raise KeyError(scene_id)


def _parse_house_count(spec: str) -> int:
    if spec == "procedural":
        return DEFAULT_PROCEDURAL_HOUSES
    text = spec.split(":", 1)[1]
    if not text.isdigit() or int(text) < 1:
        raise InputError("command line", "--scenes", "'procedural' or 'procedural:K' with K >= 1", spec)
    return int(text)


def _find_map_dirs(path: Path) -> dict[str, Path]:
    from drivenav.envs.rosmap import find_map_yaml, is_map_scene_dir, read_map_yaml

    if not path.exists():
        raise InputError(path, "--scenes", "'procedural', a scene directory, or a folder of scene directories")
    path = path.resolve()
    if path.is_file() or is_map_scene_dir(path) or any(path.glob("*.yaml")):
        read_map_yaml(find_map_yaml(path))  # a broken map names its own file and field
        directory = path.parent if path.is_file() else path
        return {directory.name: path}
    found = {child.name: child for child in sorted(path.iterdir()) if child.is_dir() and is_map_scene_dir(child)}
    if not found:
        raise InputError(path, "--scenes", "a scene directory (map YAML + image) or a folder of them", "no map found")
    return found
