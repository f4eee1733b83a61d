"""The embedded world's scene: a 2.5-D floor plan (structure grid), rooms, and objects as boxes.

Grids follow :mod:`drivenav.grid`. The structure grid holds one material per cell (:class:`Material`): walls,
door frames and unknown space are full height (floor to ceiling), sensor-opaque and not navigable. Objects are
boxes standing on the floor (or mounted at ``elevation``); those whose vertical extent reaches below the agent's
height block navigation, except floor items no taller than :data:`MAX_CLIMB` that the agent rolls over (like
Habitat's navmesh step height; the mapper's obstacle band starts at the same height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.edt import edt
from drivenav.grid import GridSpec

MAX_CLIMB = 0.15  # metres: floor objects this low do not block the agent


class Material(IntEnum):
    """Cell materials of the structure grid."""

    FREE = 0
    WALL = 1
    DOOR_FRAME = 2
    UNKNOWN = 3


@dataclass(frozen=True)
class ObjectInstance:
    """A box-shaped object in the world frame.

    ``size`` is ``(sx, sy, sz)``: extent along the object's own x and y axes (rotated by ``yaw``) and height.
    ``elevation`` is the height of the box's bottom above the floor (0 for furniture, > 0 for wall-mounted items).
    """

    instance_id: int
    category: str
    center: tuple[float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0
    elevation: float = 0.0

    @property
    def top(self) -> float:
        return self.elevation + self.size[2]

    def blocks(self, agent_height: float) -> bool:
        """Whether the object blocks the agent's body: it reaches below ``agent_height`` and is taller than
        :data:`MAX_CLIMB` (lower floor items are rolled over)."""
        return self.elevation < agent_height and self.top > MAX_CLIMB

    def footprint(self) -> NDArray[np.float64]:
        """The four footprint corners ``(4, 2)`` in the world frame, counter-clockwise."""
        hx, hy = self.size[0] / 2.0, self.size[1] / 2.0
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s], [s, c]])
        corners: NDArray[np.float64] = local @ rot.T + np.asarray(self.center)
        return corners

    def contains(self, x: NDArray[np.float64], y: NDArray[np.float64], margin: float = 0.0) -> NDArray[np.bool_]:
        """Whether world points lie inside the footprint grown by ``margin``."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = x - self.center[0], y - self.center[1]
        u, v = c * dx + s * dy, -s * dx + c * dy
        return (np.abs(u) <= self.size[0] / 2.0 + margin) & (np.abs(v) <= self.size[1] / 2.0 + margin)

    def distance(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """Euclidean distance from world points to the footprint (0 inside)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = x - self.center[0], y - self.center[1]
        u, v = c * dx + s * dy, -s * dx + c * dy
        du = np.maximum(np.abs(u) - self.size[0] / 2.0, 0.0)
        dv = np.maximum(np.abs(v) - self.size[1] / 2.0, 0.0)
        distance: NDArray[np.float64] = np.hypot(du, dv)
        return distance


@dataclass(frozen=True)
class Room:
    """A named room (its type, e.g. ``"kitchen"``) as a polygon in the world frame."""

    name: str
    polygon: tuple[tuple[float, float], ...]

    def contains(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Even-odd point-in-polygon test for world points."""
        inside = np.zeros(np.shape(x), dtype=bool)
        pts = self.polygon
        n = len(pts)
        for k in range(n):
            x0, y0 = pts[k]
            x1, y1 = pts[(k + 1) % n]
            if y0 == y1:
                continue
            crosses = (y0 > y) != (y1 > y)
            x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            inside ^= crosses & (x < x_at)
        return inside


@dataclass
class Scene:
    """A complete embedded scene.

    ``structure`` is a uint8 grid of :class:`Material` values on ``grid``. Cells outside the grid count as
    :attr:`Material.UNKNOWN`.
    """

    scene_id: str
    grid: GridSpec
    structure: NDArray[np.uint8]
    objects: list[ObjectInstance] = field(default_factory=list)
    rooms: list[Room] = field(default_factory=list)
    ceiling_height: float = 2.6
    source: str = ""

    def __post_init__(self) -> None:
        if self.structure.shape != self.grid.shape:
            raise ValueError(f"structure shape {self.structure.shape} != grid shape {self.grid.shape}")

    @cached_property
    def room_index(self) -> NDArray[np.int16]:
        """Per cell: 1 + index into :attr:`rooms` of the room containing the cell centre, 0 if none."""
        index = np.zeros(self.grid.shape, dtype=np.int16)
        for k, room in enumerate(self.rooms):
            block = self.grid.block_covering(room.polygon)
            gx, gy = self.grid.cell_centers(*block)
            part = index[block]
            part[(part == 0) & room.contains(gx, gy)] = k + 1
        return index

    def blocking_objects(self, agent_height: float) -> list[ObjectInstance]:
        """Objects that block the agent's body: below ``agent_height`` and taller than :data:`MAX_CLIMB`."""
        return [o for o in self.objects if o.blocks(agent_height)]

    def obstacle_grid(self, agent_height: float) -> NDArray[np.bool_]:
        """Cells the agent's body cannot overlap: non-free structure and blocking object footprints."""
        blocked: NDArray[np.bool_] = self.structure != Material.FREE
        half = self.grid.resolution / 2.0
        for obj in self.blocking_objects(agent_height):
            block = self.grid.block_covering(obj.footprint(), margin=2.0 * half)  # covers a rotated margin
            blocked[block] |= obj.contains(*self.grid.cell_centers(*block), margin=half)
        return blocked

    def navigable_grid(self, agent_radius: float, agent_height: float) -> NDArray[np.bool_]:
        """Cells whose centre is farther than ``agent_radius`` from every obstacle cell's face."""
        key = (round(agent_radius, 6), round(agent_height, 6))
        cached = self._navigable_cache.get(key)
        if cached is None:
            obstacles = self.obstacle_grid(agent_height)
            # Distance from the cell centre to the nearest obstacle cell's face (half a cell nearer than its centre).
            clearance = (edt(obstacles) - 0.5) * self.grid.resolution
            cached = np.asarray(clearance > agent_radius)
            self._navigable_cache[key] = cached
        return cached

    @cached_property
    def _navigable_cache(self) -> dict[tuple[float, float], NDArray[np.bool_]]:
        return {}

    def object_by_id(self, instance_id: int) -> ObjectInstance:
        for obj in self.objects:
            if obj.instance_id == instance_id:
                return obj
        raise KeyError(instance_id)

    def categories(self) -> list[str]:
        """Distinct object categories present, sorted."""
        return sorted({o.category for o in self.objects})
