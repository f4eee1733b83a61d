"""Debug picture of one directions step: map layers, FMM paths, the R_e circle, bearings and labelled frontiers."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from drivenav.directions.types import DirectionResult
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DirectionConfig

PALETTE = (
    (230, 25, 75),
    (60, 180, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (210, 245, 60),
    (0, 128, 128),
    (170, 110, 40),
    (128, 0, 0),
    (0, 0, 128),
)
UNREACHABLE = (120, 120, 120)
RAY_LENGTH = 2.0  # metres


def label_color(label: int) -> tuple[int, int, int]:
    return PALETTE[label % len(PALETTE)]


def _background(snapshot: MapSnapshot) -> NDArray[np.uint8]:
    img = np.full((*snapshot.obstacle.shape, 3), 45, np.uint8)  # unexplored
    img[snapshot.explored] = (175, 175, 160)  # explored, not navigable
    img[snapshot.navigable] = (250, 250, 250)
    img[snapshot.obstacle] = (0, 0, 0)
    return np.ascontiguousarray(img[::-1])  # row 0 (lowest y) at the bottom of the picture


class _Canvas:
    """World metres -> picture pixels (``scale`` pixels per cell, +y up)."""

    def __init__(self, grid: GridSpec, scale: int) -> None:
        self.grid = grid
        self.scale = scale
        self.height = grid.shape[0] * scale

    def px(self, xy: Sequence[float]) -> tuple[float, float]:
        u = (xy[0] - self.grid.origin[0]) / self.grid.resolution * self.scale
        v = self.height - (xy[1] - self.grid.origin[1]) / self.grid.resolution * self.scale
        return float(u), float(v)

    def length(self, metres: float) -> float:
        return metres / self.grid.resolution * self.scale


def draw_directions(
    snapshot: MapSnapshot,
    frontiers: Sequence[Frontier],
    result: DirectionResult,
    robot_xy: Sequence[float],
    path: str | Path,
    config: DirectionConfig | None = None,
    scale: int = 2,
) -> None:
    """Write a PNG: map, FMM paths and frontier cells coloured by direction label (grey: unreachable),
    the robot-centred R_e circle, the p_i points, and one ray per direction along its mean bearing."""
    cfg = config or DirectionConfig()
    image = Image.fromarray(_background(snapshot)).resize(
        (snapshot.grid.shape[1] * scale, snapshot.grid.shape[0] * scale), Image.Resampling.NEAREST
    )
    draw = ImageDraw.Draw(image)
    canvas = _Canvas(snapshot.grid, scale)
    colour_of = {fid: label_color(d.label) for d in result.directions for fid in d.frontier_ids}
    for frontier in frontiers:
        colour = colour_of.get(frontier.frontier_id, UNREACHABLE)
        for point in frontier.points:
            u, v = canvas.px(point)
            draw.rectangle((u - scale / 2, v - scale / 2, u + scale / 2, v + scale / 2), fill=colour)
    for fid, fpath in result.paths.items():
        colour = colour_of.get(fid, UNREACHABLE)
        draw.line([canvas.px(p) for p in fpath.path], fill=colour, width=max(scale // 2, 1))
        u, v = canvas.px(fpath.bearing_point)
        draw.ellipse((u - 3, v - 3, u + 3, v + 3), outline=colour, width=2)
    ru, rv = canvas.px(robot_xy)
    radius = canvas.length(cfg.bearing_radius)
    draw.ellipse((ru - radius, rv - radius, ru + radius, rv + radius), outline=(255, 140, 0), width=1)
    for direction in result.directions:
        end = (
            robot_xy[0] + RAY_LENGTH * np.cos(direction.bearing),
            robot_xy[1] + RAY_LENGTH * np.sin(direction.bearing),
        )
        colour = label_color(direction.label)
        draw.line([(ru, rv), canvas.px(end)], fill=colour, width=3)
        draw.text(canvas.px(end), f"D{direction.label}", fill=colour)
    draw.ellipse((ru - 4, rv - 4, ru + 4, rv + 4), fill=(255, 0, 0))
    image.save(path)
