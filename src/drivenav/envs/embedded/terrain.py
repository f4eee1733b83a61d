"""Where the embedded world's agent can go, for one-floor scenes and buildings alike: placing a start, the motion
model, and geodesic distance fields (what the env, its measures, the oracle and the episode generators use).

A one-floor :class:`~drivenav.envs.embedded.scene.Scene` is a :class:`FlatTerrain`: its navigable grid, its largest
4-connected component, scikit-fmm's distances and the sliding step of :mod:`drivenav.envs.embedded.motion`, every
height 0 -- exactly the one-floor world as it always was. A :class:`~drivenav.envs.embedded.building.Building` is a
:class:`LevelTerrain` over its walking surfaces (:mod:`drivenav.envs.embedded.levels`): points carry their height,
distances run up and down the stairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.geodesic import GeodesicField, largest_component
from drivenav.envs.embedded.levels import LevelField, Levels, Point3
from drivenav.envs.embedded.motion import forward_step, is_navigable
from drivenav.envs.embedded.scene import Scene
from drivenav.grid import GridSpec
from drivenav.types import SimConfig

START_TOLERANCE = 0.25  # metres between an episode's start or view point height and the floor it stands on


class DistanceField(Protocol):
    """Geodesic distance to a set of goals from any point."""

    @property
    def distances(self) -> NDArray[np.float64]:
        """Per layer (one for a one-floor scene) and cell: metres to the nearest goal (``inf``: no path)."""
        ...

    def at(self, x: float, y: float, z: float = 0.0) -> float:
        """Metres from the world point ``(x, y)`` at height ``z`` (``inf``: no path)."""
        ...


class Terrain(Protocol):
    """The navigable space of one scene or building."""

    @property
    def grid(self) -> GridSpec: ...

    @property
    def reachable(self) -> NDArray[np.bool_]:
        """Per layer (one for a one-floor scene) and cell: the connected navigable area episodes start in."""
        ...

    @property
    def heights(self) -> NDArray[np.float64]:
        """Per layer and cell: the walking surface's height (NaN where there is none)."""
        ...

    def place(self, x: float, y: float, z: float) -> float | None:
        """The height of the navigable floor under a world point near height ``z`` (None where there is none)."""
        ...

    def on_reachable(self, x: float, y: float, z: float) -> bool:
        """Whether a world point near height ``z`` lies on the reachable area."""
        ...

    def forward(self, x: float, y: float, z: float, yaw: float, step: float) -> tuple[Point3, bool]:
        """Where a straight move of ``step`` metres along ``yaw`` ends (sliding along obstacles), and whether it
        collided."""
        ...

    def field(self, goals: Sequence[Point3]) -> DistanceField:
        """Distances over the reachable area to the nearest of ``goals``."""
        ...


@dataclass(frozen=True)
class _FlatField:
    field: GeodesicField

    @property
    def distances(self) -> NDArray[np.float64]:
        return self.field.distances[None]

    def at(self, x: float, y: float, z: float = 0.0) -> float:
        return self.field.at(x, y)


class FlatTerrain:
    """A one-floor scene's navigable grid (heights 0)."""

    def __init__(self, scene: Scene, sim: SimConfig) -> None:
        self.scene = scene
        self.navigable = scene.navigable_grid(sim.agent_radius, sim.agent_height)

    @property
    def grid(self) -> GridSpec:
        return self.scene.grid

    @cached_property
    def flat_reachable(self) -> NDArray[np.bool_]:
        """The largest 4-connected navigable component (where episodes start and goals are measured)."""
        return largest_component(self.navigable)

    @property
    def reachable(self) -> NDArray[np.bool_]:
        return self.flat_reachable[None]

    @cached_property
    def heights(self) -> NDArray[np.float64]:
        return np.where(self.scene.structure == 0, 0.0, np.nan)[None]

    def place(self, x: float, y: float, z: float) -> float | None:
        return 0.0 if is_navigable(self.navigable, self.grid, x, y) else None

    def on_reachable(self, x: float, y: float, z: float) -> bool:
        row, col = self.grid.cell_at(x, y)
        rows, cols = self.grid.shape
        return bool(0 <= row < rows and 0 <= col < cols and self.flat_reachable[row, col])

    def forward(self, x: float, y: float, z: float, yaw: float, step: float) -> tuple[Point3, bool]:
        nx, ny, collided = forward_step(self.navigable, self.grid, x, y, yaw, step)
        return (nx, ny, 0.0), collided

    def field(self, goals: Sequence[Point3]) -> DistanceField:
        return _FlatField(GeodesicField(self.flat_reachable, self.grid, [(x, y) for x, y, _ in goals]))


class LevelTerrain:
    """A building's walking surfaces (:class:`~drivenav.envs.embedded.levels.Levels`)."""

    def __init__(self, building: Building, sim: SimConfig) -> None:
        self.building = building
        self.levels = Levels(building, sim.agent_radius, sim.agent_height)

    @property
    def grid(self) -> GridSpec:
        return self.building.grid

    @property
    def reachable(self) -> NDArray[np.bool_]:
        return self.levels.reachable

    @property
    def heights(self) -> NDArray[np.float64]:
        return self.levels.heights

    def place(self, x: float, y: float, z: float) -> float | None:
        node = self.levels.node_at(x, y, z, START_TOLERANCE)
        return None if node is None else self.levels.height(node)

    def on_reachable(self, x: float, y: float, z: float) -> bool:
        node = self.levels.node_at(x, y, z, START_TOLERANCE)
        return node is not None and bool(self.levels.reachable[node.layer, node.row, node.col])

    def forward(self, x: float, y: float, z: float, yaw: float, step: float) -> tuple[Point3, bool]:
        return self.levels.forward(x, y, z, yaw, step)

    def field(self, goals: Sequence[Point3]) -> DistanceField:
        return LevelField(self.levels, [g for g in goals if self.on_reachable(*g)], START_TOLERANCE)


def terrain_of(world: Scene | Building, sim: SimConfig) -> Terrain:
    """The terrain of a one-floor scene or of a building."""
    return LevelTerrain(world, sim) if isinstance(world, Building) else FlatTerrain(world, sim)
