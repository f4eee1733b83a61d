"""A hand-built two-storey building for the floors tests: two 8 x 5 m floors, 3 m apart, joined by one straight
flight along x (16 risers of 0.1875 m, treads of 0.27 m, 1 m wide), with an object on each floor."""

from __future__ import annotations

import numpy as np

from drivenav.envs.embedded.building import Building, Flight, Staircase, Storey
from drivenav.envs.embedded.goals import scene_goals
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.grid import GridSpec
from drivenav.types import SimConfig

RES = 0.05
LENGTH, WIDTH = 8.0, 5.0
STOREY = 3.0
FLIGHT = Flight(foot=(2.0, 2.5), heading=0, width=1.0, risers=16, riser=0.1875, going=0.27, base=0.0)
"""Its foot at x = 2 m, its top at x = 2 + 15 * 0.27 = 6.05 m, between y = 2 and 3 m."""


def floor(scene_id: str, objects: list[ObjectInstance]) -> Scene:
    """One storey: a rectangle with one-cell outer walls (free x in [0.05, 7.95], y in [0.05, 4.95])."""
    rows, cols = round(WIDTH / RES), round(LENGTH / RES)
    structure = np.zeros((rows, cols), np.uint8)
    structure[0, :] = structure[-1, :] = Material.WALL
    structure[:, 0] = structure[:, -1] = Material.WALL
    polygon = ((0.0, 0.0), (LENGTH, 0.0), (LENGTH, WIDTH), (0.0, WIDTH))
    grid = GridSpec(RES, (0.0, 0.0), (rows, cols))
    return Scene(scene_id, grid, structure, objects, [Room("hallway", polygon)], ceiling_height=STOREY - 0.2)


def two_floors() -> Building:
    """The two-storey test building: a chair downstairs by the west wall, a bed upstairs by the east wall."""
    chair = ObjectInstance(1, "chair", (0.6, 0.8), (0.5, 0.5, 0.9))
    bed = ObjectInstance(2, "bed", (7.2, 0.9), (1.0, 1.2, 0.6))
    storeys = (Storey(floor("test/two", [chair]), 0.0), Storey(floor("test/two", [bed]), STOREY))
    return Building("test/two", storeys, (Staircase(0, (FLIGHT,)),), source="test")


def building_episode(
    building: Building, start: tuple[float, float, float], category: str, episode_id: str = "0", yaw: float = 0.0
) -> Episode:
    """An episode in ``building`` from world point ``start`` (x, y, height), facing ``yaw`` (radians from +x), to
    the objects of ``category`` (their view points for Habitat's default sensor)."""
    goals = scene_goals(building, SimConfig())
    return Episode(
        episode_id=episode_id,
        scene_id=building.scene_id,
        start_position=world_to_habitat(*start),
        start_rotation=yaw_to_quaternion(yaw),
        object_category=category,
        goals=tuple(goals.goals[category]),
        info={"canonical_category": category},
    )
