"""The embedded world's goals: each object's view points, and per scene the reachable region, the goals by category
and their geodesic fields (what episodes are generated and checked against).

Goal view points: navigable positions within 1.0 m of an object from which it is visible, on the object's own
floor (in a building: on that storey's floor, not on its stairs).

Visibility in the 2.5-D world: a straight line from the view point to the object's footprint that crosses no
structure (walls, door frames, unknown), and some part of the object inside the camera's vertical field of view
at that distance (a low object right under the camera is not visible; the agent may turn to face it, so the
horizontal field of view does not restrict view points).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import Building, storeys_of
from drivenav.envs.embedded.levels import Point3
from drivenav.envs.embedded.rosmap import OBJECTS_FILE
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.envs.embedded.terrain import DistanceField, Terrain, terrain_of
from drivenav.episode import ObjectGoal, ViewPoint, world_to_habitat, yaw_to_quaternion
from drivenav.errors import InputError
from drivenav.grid import GridSpec
from drivenav.types import SimConfig

VIEW_POINT_RADIUS = 1.0  # metres from the object footprint (Habitat ObjectNav view points)
VIEW_POINT_SPACING = 0.2  # metres between view points: 0.25 m discs around them cover the view region


def _line_of_sight(scene: Scene, start: NDArray[np.float64], end: NDArray[np.float64]) -> NDArray[np.bool_]:
    """For ``(N, 2)`` start/end points: whether the segment crosses no structure cell."""
    step = scene.grid.resolution / 2.0
    length = np.linalg.norm(end - start, axis=1)
    samples = max(2, int(np.ceil(length.max(initial=0.0) / step)) + 1)
    t = np.linspace(0.0, 1.0, samples)[None, :, None]
    points = start[:, None, :] + t * (end - start)[:, None, :]
    cells = scene.grid.world_to_cell(points)
    inside = scene.grid.contains(cells)
    rows = np.clip(cells[..., 0], 0, scene.grid.shape[0] - 1)
    cols = np.clip(cells[..., 1], 0, scene.grid.shape[1] - 1)
    clear = inside & (scene.structure[rows, cols] == Material.FREE)
    return np.asarray(np.all(clear, axis=1))


def _nearest_footprint_points(obj: ObjectInstance, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The closest point of the object's footprint to each of ``points`` (world frame)."""
    c, s = math.cos(obj.yaw), math.sin(obj.yaw)
    d = points - np.asarray(obj.center)
    u = np.clip(c * d[:, 0] + s * d[:, 1], -obj.size[0] / 2.0, obj.size[0] / 2.0)
    v = np.clip(-s * d[:, 0] + c * d[:, 1], -obj.size[1] / 2.0, obj.size[1] / 2.0)
    nearest: NDArray[np.float64] = np.asarray(obj.center) + np.stack([c * u - s * v, s * u + c * v], axis=1)
    return nearest


def _within_vertical_fov(obj: ObjectInstance, points: NDArray[np.float64], sim: SimConfig) -> NDArray[np.bool_]:
    """Whether some part of the object lies inside the vertical field of view from each point."""
    intr = sim.intrinsics
    tan_half = (intr.height / 2.0) / intr.fy
    corners = obj.footprint()
    far = np.max(np.linalg.norm(points[:, None, :] - corners[None, :, :], axis=2), axis=1)
    near = np.maximum(obj.distance(points[:, 0], points[:, 1]), 1e-3)
    below_ok = (sim.camera_height - obj.top) <= tan_half * far
    above_ok = (obj.elevation - sim.camera_height) <= tan_half * near
    return np.asarray(below_ok & above_ok)


def view_point_cells(
    scene: Scene, obj: ObjectInstance, reachable: NDArray[np.bool_], sim: SimConfig
) -> NDArray[np.float64]:
    """World positions ``(N, 2)`` of reachable cells (on a ``VIEW_POINT_SPACING`` lattice) that see ``obj``."""
    res = scene.grid.resolution
    stride = max(1, round(VIEW_POINT_SPACING / res))
    corners = obj.footprint()
    lo = scene.grid.world_to_cell(corners.min(axis=0) - VIEW_POINT_RADIUS)
    hi = scene.grid.world_to_cell(corners.max(axis=0) + VIEW_POINT_RADIUS)
    r0, c0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    r1, c1 = min(int(hi[0]) + 1, scene.grid.shape[0]), min(int(hi[1]) + 1, scene.grid.shape[1])
    rows, cols = np.mgrid[r0:r1, c0:c1]
    keep = (rows % stride == 0) & (cols % stride == 0) & reachable[r0:r1, c0:c1]
    points = scene.grid.cell_to_world(np.stack([rows[keep], cols[keep]], axis=1))
    if len(points) == 0:
        return points
    points = points[obj.distance(points[:, 0], points[:, 1]) <= VIEW_POINT_RADIUS]
    if len(points) == 0:
        return points
    targets = _nearest_footprint_points(obj, points)
    # Stop the sight line just short of the footprint so the object's own cell is not tested as structure.
    direction = targets - points
    norm = np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-9)
    shortened = targets - direction / norm * np.minimum(norm, res)
    visible = _line_of_sight(scene, points, shortened) & _within_vertical_fov(obj, points, sim)
    return points[visible]


def object_goal(
    scene: Scene, obj: ObjectInstance, reachable: NDArray[np.bool_], sim: SimConfig, elevation: float = 0.0
) -> ObjectGoal:
    """The goal entry of one object of a floor at ``elevation``: its Habitat position and its view points facing
    it, on ``reachable`` cells of that floor."""
    points = view_point_cells(scene, obj, reachable, sim)
    view_points = []
    for x, y in points:
        yaw = math.atan2(obj.center[1] - y, obj.center[0] - x)
        view_points.append(ViewPoint(world_to_habitat(x, y, elevation), yaw_to_quaternion(yaw)))
    centre = world_to_habitat(obj.center[0], obj.center[1], elevation + obj.elevation + obj.size[2] / 2.0)
    return ObjectGoal(obj.instance_id, obj.category, centre, tuple(view_points))


@dataclass
class SceneGoals:
    """Per scene or building: where the agent can go, goals by category, and distance fields (built lazily)."""

    scene: Scene | Building
    terrain: Terrain
    goals: dict[str, list[ObjectGoal]]
    fields: dict[str, DistanceField] = field(default_factory=dict)

    @property
    def reachable(self) -> NDArray[np.bool_]:
        """Per layer (one for a one-floor scene) and cell: the reachable area."""
        return self.terrain.reachable

    @property
    def grid(self) -> GridSpec:
        return self.terrain.grid

    def field_for(self, category: str) -> DistanceField:
        if category not in self.fields:
            self.fields[category] = self.terrain.field(view_points_of(self.goals[category]))
        return self.fields[category]


def view_points_of(goals: Sequence[ObjectGoal]) -> list[Point3]:
    """The goals' view points as world points with their heights."""
    return [(*vp.xy, vp.height) for goal in goals for vp in goal.view_points]


GENERATED = {"procedural": "procedural house", "homes": "generated home", "storeys": "generated home"}
"""What errors call a generated scene, by its ``source``."""


def _scene_source(scene: Scene | Building) -> str:
    """What errors about a scene name: its map YAML, or the generated house."""
    kind = GENERATED.get(scene.source)
    return scene.source if kind is None else f"{kind} {scene.scene_id}"


def objects_source(scene: Scene | Building) -> str:
    """What errors about a scene's objects name: the map's objects.json where it has one, else the scene."""
    objects = Path(scene.source).with_name(OBJECTS_FILE)
    return str(objects) if scene.source not in GENERATED and objects.is_file() else _scene_source(scene)


def scene_goals(scene: Scene | Building, sim: SimConfig) -> SceneGoals:
    """Goals of every object that has at least one reachable view point on its own floor, grouped by category.

    A scene without free space the agent fits in, or without an object it can reach, is an :class:`InputError`
    naming the scene's file or its objects.json (never a scene silently left out of the episodes).
    """
    terrain = terrain_of(scene, sim)
    if not terrain.reachable.any():
        expected = f"free space an agent of radius {sim.agent_radius} m fits in"
        raise InputError(_scene_source(scene), "image", expected, "only walls, unknown or too narrow space")
    goals: dict[str, list[ObjectGoal]] = {}
    for j, storey in enumerate(storeys_of(scene)):
        floor = terrain.reachable[j] & (terrain.heights[j] == storey.elevation)
        for obj in storey.plan.objects:
            goal = object_goal(storey.plan, obj, floor, sim, storey.elevation)
            if goal.view_points:
                goals.setdefault(obj.category, []).append(goal)
    if not goals:
        expected = "objects seen from where the agent can go (objects.json, or free space to place them in)"
        objects = sum(len(storey.plan.objects) for storey in storeys_of(scene))
        raise InputError(objects_source(scene), "objects", expected, f"{objects} objects, none reachable")
    return SceneGoals(scene, terrain, goals)
