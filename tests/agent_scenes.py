"""Hand-built embedded scenes for scripted agent tests: corridors, junctions, dead ends, blocked doors."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivenav.envs.embedded.goals import scene_goals
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.grid import GridSpec
from drivenav.types import SimConfig

RES = 0.05
Rect = tuple[float, float, float, float]  # xmin, ymin, xmax, ymax in metres


def carved_scene(
    scene_id: str, free: Sequence[Rect], objects: Sequence[ObjectInstance] = (), size: float = 24.0
) -> Scene:
    """A scene that is wall everywhere except the given free rectangles (world origin at the grid corner)."""
    cells = round(size / RES)
    structure = np.full((cells, cells), Material.WALL, dtype=np.uint8)
    for xmin, ymin, xmax, ymax in free:
        structure[round(ymin / RES) : round(ymax / RES), round(xmin / RES) : round(xmax / RES)] = Material.FREE
    return Scene(scene_id, GridSpec(RES, (0.0, 0.0), (cells, cells)), structure, list(objects))


def episode_for(scene: Scene, start: tuple[float, float], yaw: float, category: str, text: str = "") -> Episode:
    """An episode in ``scene`` from ``start`` looking for every instance of ``category`` (named ``text``)."""
    goals = scene_goals(scene, SimConfig())
    field = goals.field_for(category)
    return Episode(
        episode_id="0",
        scene_id=scene.scene_id,
        start_position=world_to_habitat(*start),
        start_rotation=yaw_to_quaternion(yaw),
        object_category=text or category,
        goals=tuple(goals.goals[category]),
        info={"geodesic_distance": field.at(*start), "canonical_category": category, "synonym": False},
    )


def t_junction(target_on_left: bool = True) -> Scene:
    """A corridor running north from (12, 2) that meets an east-west corridor at y = 14 (a T)."""
    free = [(11.25, 1.5, 12.75, 15.5), (3.0, 14.0, 21.0, 15.5)]
    x = 3.4 if target_on_left else 20.6
    plant = ObjectInstance(1, "plant", (x, 14.75), (0.5, 0.5, 1.2))
    return carved_scene("test/t_junction", free, [plant])
