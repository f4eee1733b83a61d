"""The floors of a world as the pictures draw them: each storey of a building, or a one-floor scene's one floor.

A point is on the floor :meth:`~drivenav.envs.embedded.building.Building.storey_at` gives for its height. On a
staircase that is the floor the stairs rise from until the agent reaches the top, so a climb or a descent is drawn
on the lower floor's map. A move between two poses on different floors (at the top of the stairs) is drawn on the
lower of the two floors too; the poses on either side of it are where the path leaves one floor and enters the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivenav.envs.embedded.building import Box3, Building, Staircase, Storey, storeys_of
from drivenav.envs.embedded.scene import Scene
from drivenav.viz.saved_trace import SavedTrace


@dataclass(frozen=True)
class Floor:
    """Storey ``index`` of ``world`` (a one-floor scene's only floor is its storey 0)."""

    world: Scene | Building
    index: int

    @property
    def storey(self) -> Storey:
        return storeys_of(self.world)[self.index]

    @property
    def plan(self) -> Scene:
        """Its walls, rooms and objects."""
        return self.storey.plan

    @property
    def elevation(self) -> float:
        """Height of its floor above the ground floor (metres)."""
        return self.storey.elevation

    @property
    def title(self) -> str:
        return f"floor {self.index} ({self.elevation:.1f} m)"

    @property
    def stairs(self) -> tuple[Staircase, ...]:
        """The staircases rising from it."""
        if isinstance(self.world, Scene):
            return ()
        return tuple(stair for stair in self.world.stairs if stair.lower == self.index)

    @property
    def stair_cells(self) -> NDArray[np.bool_] | None:
        """The cells of the stairs rising from it (None on a one-floor scene)."""
        return None if isinstance(self.world, Scene) else self.world.stair_cells[self.index]

    @property
    def hole(self) -> NDArray[np.bool_] | None:
        """Its stairwell: the cells where it is open onto the floor below (None on a one-floor scene)."""
        return None if isinstance(self.world, Scene) else self.world.holes[self.index]

    @property
    def railings(self) -> tuple[Box3, ...]:
        """The railings along its stairwell."""
        return () if isinstance(self.world, Scene) else self.world.railings[self.index]

    @property
    def boxes(self) -> tuple[Box3, ...]:
        """Every step, landing and railing of the world (none in a one-floor scene)."""
        return () if isinstance(self.world, Scene) else self.world.structure_boxes

    def holds(self, height: float) -> bool:
        """Whether a point of this height is on this floor."""
        return int(floor_at(self.world, height)) == self.index


def floors_of(world: Scene | Building) -> tuple[Floor, ...]:
    """The world's floors, the ground floor first."""
    return tuple(Floor(world, index) for index in range(len(storeys_of(world))))


def floor_at(world: Scene | Building, heights: ArrayLike) -> NDArray[np.int64]:
    """The index of the floor each height is on (0 throughout on a one-floor scene), in the shape of ``heights``."""
    z = np.asarray(heights, dtype=np.float64)
    if isinstance(world, Scene):
        return np.zeros(z.shape, dtype=np.int64)
    return np.array([world.storey_at(float(h)) for h in z.ravel()], dtype=np.int64).reshape(z.shape)


def pose_floors(world: Scene | Building, trace: SavedTrace) -> NDArray[np.int64]:
    """Per pose of the trace, the floor it is on."""
    return floor_at(world, trace.heights)


def move_floors(floors: NDArray[np.int64]) -> NDArray[np.int64]:
    """Per move ``t`` (pose ``t`` to ``t + 1``) of poses on ``floors``: the floor its line is drawn on, the lower of
    its two poses' floors."""
    return np.minimum(floors[:-1], floors[1:])


def floor_changes(floors: NDArray[np.int64]) -> list[int]:
    """The moves ``t`` whose poses ``t`` and ``t + 1`` are on different floors."""
    return [int(t) for t in np.flatnonzero(floors[:-1] != floors[1:])]
