"""The area an episode explored, approximated from its trajectory alone (no depth frames are stored).

A cell counts as explored when some visited pose sees it: within ``max_range`` of the camera, inside the
horizontal field of view, with a clear line of sight. Sight is blocked by non-free structure (walls, door
frames, unknown space) and by objects that span the camera height; the first blocking cell is itself seen.
Rays are cast in the plane, ``RAYS_PER_RADIAN`` of them per radian of field of view, sampled every half cell.

In a building each storey has its own explored cells: those seen from the poses on it (:mod:`drivenav.viz.floors`),
past its own walls and objects and the steps, landings and railings that span the camera's height there.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import Building, rect_cells
from drivenav.envs.embedded.scene import Material, Scene
from drivenav.types import SimConfig
from drivenav.viz.floors import Floor, floors_of, pose_floors
from drivenav.viz.saved_trace import SavedTrace

RAYS_PER_RADIAN = 100  # at 5 m, neighbouring rays are 5 cm apart: one cell
POSES_PER_CHUNK = 32  # bounds the memory of one vectorised batch of rays


def opaque_cells(scene: Scene, camera_height: float) -> NDArray[np.bool_]:
    """Cells that block a level line of sight at ``camera_height``."""
    opaque: NDArray[np.bool_] = scene.structure != Material.FREE
    gx, gy = scene.grid.cell_centers()
    for obj in scene.objects:
        if obj.elevation <= camera_height <= obj.top:
            opaque |= obj.contains(gx, gy)
    return opaque


def floor_opaque_cells(floor: Floor, camera_height: float) -> NDArray[np.bool_]:
    """Cells of a floor that block a level line of sight ``camera_height`` above it: its plan's
    (:func:`opaque_cells`) and those of the building's steps, landings and railings at that height."""
    opaque = opaque_cells(floor.plan, camera_height)
    eye = floor.elevation + camera_height
    for box in floor.boxes:
        if box.bottom <= eye <= box.top:
            opaque |= rect_cells(floor.plan.grid, box.rect)
    return opaque


def explored_cells(
    world: Scene | Building, trace: SavedTrace, sim: SimConfig, max_range: float = 5.0, floor: int = 0
) -> NDArray[np.bool_]:
    """Boolean grid (the world's shape) of the cells of floor ``floor`` seen from the trajectory's poses on it
    (a one-floor scene: every pose)."""
    level = floors_of(world)[floor]
    grid = level.plan.grid
    opaque = floor_opaque_cells(level, sim.camera_height)
    explored = np.zeros_like(opaque)
    on_floor = pose_floors(world, trace) == floor
    poses = np.unique(np.column_stack([trace.positions, trace.yaws])[on_floor].round(3), axis=0)
    half_fov = math.radians(sim.hfov_deg) / 2.0
    offsets = np.linspace(-half_fov, half_fov, max(2, round(2.0 * half_fov * RAYS_PER_RADIAN)))
    ranges = np.arange(0.0, max_range, grid.resolution / 2.0)
    for begin in range(0, len(poses), POSES_PER_CHUNK):
        chunk = poses[begin : begin + POSES_PER_CHUNK]
        angles = chunk[:, 2, None] + offsets[None, :]  # (poses, rays)
        xs = chunk[:, 0, None, None] + np.cos(angles)[..., None] * ranges  # (poses, rays, samples)
        ys = chunk[:, 1, None, None] + np.sin(angles)[..., None] * ranges
        cells = grid.world_to_cell(np.stack([xs, ys], axis=-1))
        inside = grid.contains(cells)
        rows = np.where(inside, cells[..., 0], 0)
        cols = np.where(inside, cells[..., 1], 0)
        blocked = ~inside | opaque[rows, cols]
        seen = inside & (np.cumsum(blocked, axis=-1) - blocked == 0)
        explored[rows[seen], cols[seen]] = True
    return explored


def explored_floors(
    world: Scene | Building, trace: SavedTrace, sim: SimConfig, max_range: float = 5.0
) -> tuple[NDArray[np.bool_], ...]:
    """Per floor of the world, ground floor first, its :func:`explored_cells`."""
    return tuple(explored_cells(world, trace, sim, max_range, f.index) for f in floors_of(world))
