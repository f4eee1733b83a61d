"""Agent motion on a navigable grid: forward steps with collision and sliding, and turns (pure functions).

Used by :class:`drivenav.envs.embedded.EmbeddedEnv` and by agents that predict their own motion (the oracle).
The agent's centre may stand on a cell of ``navigable`` (``Scene.navigable_grid``); points outside the grid
are not navigable. A forward step is checked along its straight segment in sub-steps of at most half a cell;
if blocked, the agent slides along the obstacle like Habitat's navmesh: from the last free point, the
remaining motion is projected on the world x and y axes and the projection that travels further is taken.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import GridSpec, wrap_angle
from drivenav.types import Action, Pose, SimConfig


def is_navigable(navigable: NDArray[np.bool_], grid: GridSpec, x: float, y: float) -> bool:
    """Whether the agent's centre may stand at world ``(x, y)``."""
    row, col = grid.cell_at(x, y)
    rows, cols = navigable.shape
    return 0 <= row < rows and 0 <= col < cols and bool(navigable[row, col])


def _free_prefix(navigable: NDArray[np.bool_], grid: GridSpec, x: float, y: float, dx: float, dy: float) -> float:
    """Largest fraction ``f`` in ``[0, 1]`` of the motion ``(dx, dy)`` whose sub-step samples are navigable.

    Samples lie at most half a cell apart; ``f`` is the last sample before the first blocked one.
    """
    length = math.hypot(dx, dy)
    if length == 0.0:
        return 0.0
    n = max(1, math.ceil(length / (0.5 * grid.resolution)))
    fractions = np.arange(1, n + 1) / n
    points = np.stack([x + fractions * dx, y + fractions * dy], axis=-1)
    cells = grid.world_to_cell(points)
    ok = grid.contains(cells)
    rows = np.clip(cells[:, 0], 0, navigable.shape[0] - 1)
    cols = np.clip(cells[:, 1], 0, navigable.shape[1] - 1)
    ok &= navigable[rows, cols]
    blocked = np.flatnonzero(~ok)
    if blocked.size == 0:
        return 1.0
    first = int(blocked[0])
    return 0.0 if first == 0 else float(fractions[first - 1])


def forward_step(
    navigable: NDArray[np.bool_], grid: GridSpec, x: float, y: float, yaw: float, distance: float
) -> tuple[float, float, bool]:
    """Move ``distance`` metres along ``yaw`` from ``(x, y)``: returns ``(new x, new y, collided)``.

    ``collided`` is True whenever the full step was not executed (the agent stopped short or slid). An agent
    that starts on a non-navigable cell does not move.
    """
    dx, dy = distance * math.cos(yaw), distance * math.sin(yaw)
    if not is_navigable(navigable, grid, x, y):
        return x, y, distance != 0.0
    f = _free_prefix(navigable, grid, x, y, dx, dy)
    if f == 1.0:
        return x + dx, y + dy, False
    bx, by = x + f * dx, y + f * dy
    rx, ry = (1.0 - f) * dx, (1.0 - f) * dy
    slide_x = _free_prefix(navigable, grid, bx, by, rx, 0.0) * abs(rx)
    slide_y = _free_prefix(navigable, grid, bx, by, 0.0, ry) * abs(ry)
    if slide_x >= slide_y:
        return bx + math.copysign(slide_x, rx), by, True
    return bx, by + math.copysign(slide_y, ry), True


def turn(yaw: float, action: Action, turn_angle: float) -> float:
    """Yaw after a turn action (``turn_angle`` in radians, left = counter-clockwise); others keep it."""
    if action == Action.TURN_LEFT:
        return wrap_angle(yaw + turn_angle)
    if action == Action.TURN_RIGHT:
        return wrap_angle(yaw - turn_angle)
    return yaw


def apply_action(
    navigable: NDArray[np.bool_], grid: GridSpec, pose: Pose, action: Action, config: SimConfig
) -> tuple[Pose, bool]:
    """The world pose after ``action`` and whether it collided (STOP does not move)."""
    if action == Action.MOVE_FORWARD:
        x, y, collided = forward_step(navigable, grid, pose.x, pose.y, pose.yaw, config.forward_step)
        return Pose(x, y, pose.yaw), collided
    return Pose(pose.x, pose.y, turn(pose.yaw, action, math.radians(config.turn_angle_deg))), False
