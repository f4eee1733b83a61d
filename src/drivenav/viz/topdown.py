"""Top-down episode pictures: walls, rooms, objects, goal and view points, start, trajectory and end."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from drivenav.envs.episode import Episode, habitat_to_world
from drivenav.envs.palette import category_color
from drivenav.envs.scene import Material, Scene

MAX_SIDE = 1000  # pixels of the longer side of the map area
MARGIN_CELLS = 10
HEADER = 28
STRUCTURE_COLORS = {
    Material.FREE: (236, 236, 230),
    Material.WALL: (45, 45, 50),
    Material.DOOR_FRAME: (140, 95, 55),
    Material.UNKNOWN: (165, 165, 170),
}


class _Canvas:
    """World-to-pixel mapping of a cropped, scaled structure grid."""

    def __init__(self, scene: Scene) -> None:
        known = np.argwhere(scene.structure != Material.UNKNOWN)
        if len(known) == 0:
            known = np.array([[0, 0], [scene.grid.shape[0] - 1, scene.grid.shape[1] - 1]])
        lo = np.maximum(known.min(axis=0) - MARGIN_CELLS, 0)
        hi = np.minimum(known.max(axis=0) + MARGIN_CELLS + 1, scene.grid.shape)
        self.rows = (int(lo[0]), int(hi[0]))
        self.cols = (int(lo[1]), int(hi[1]))
        side = max(hi[0] - lo[0], hi[1] - lo[1])
        self.scale = max(1, MAX_SIDE // int(side))
        self.res = scene.grid.resolution
        self.x0 = scene.grid.origin[0] + self.cols[0] * self.res
        self.y1 = scene.grid.origin[1] + self.rows[1] * self.res

    def to_pixel(self, x: float, y: float) -> tuple[float, float]:
        return (x - self.x0) / self.res * self.scale, (self.y1 - y) / self.res * self.scale + HEADER

    def base_image(self, scene: Scene) -> Image.Image:
        window = scene.structure[self.rows[0] : self.rows[1], self.cols[0] : self.cols[1]]
        rgb = np.zeros((*window.shape, 3), dtype=np.uint8)
        for material, color in STRUCTURE_COLORS.items():
            rgb[window == material] = color
        rooms = scene.room_index[self.rows[0] : self.rows[1], self.cols[0] : self.cols[1]]
        tinted = (rooms > 0) & (window == Material.FREE)
        rgb[tinted & (rooms % 2 == 0)] = (226, 232, 238)
        picture = np.repeat(np.repeat(rgb[::-1], self.scale, axis=0), self.scale, axis=1)
        header = np.full((HEADER, picture.shape[1], 3), 255, dtype=np.uint8)
        return Image.fromarray(np.concatenate([header, picture]))


def _darker(color: tuple[int, int, int], factor: float = 0.6) -> tuple[int, int, int]:
    r, g, b = color
    return int(r * factor), int(g * factor), int(b * factor)


def _draw_rooms(draw: ImageDraw.ImageDraw, canvas: _Canvas, scene: Scene) -> None:
    for room in scene.rooms:
        xs, ys = zip(*room.polygon, strict=True)
        px, py = canvas.to_pixel(sum(xs) / len(xs), sum(ys) / len(ys))
        draw.text((px, py), room.name, fill=(120, 120, 140), anchor="mm")


def _draw_objects(draw: ImageDraw.ImageDraw, canvas: _Canvas, scene: Scene, goal_ids: set[int]) -> None:
    for obj in scene.objects:
        corners = [canvas.to_pixel(x, y) for x, y in obj.footprint()]
        color = category_color(obj.category)
        is_goal = obj.instance_id in goal_ids
        draw.polygon(corners, fill=color, outline=(220, 20, 20) if is_goal else _darker(color))
        if is_goal:
            draw.line([*corners, corners[0]], fill=(220, 20, 20), width=3)


def _draw_pose(
    draw: ImageDraw.ImageDraw,
    canvas: _Canvas,
    xy: tuple[float, float],
    yaw: float,
    color: tuple[int, int, int],
) -> None:
    px, py = canvas.to_pixel(*xy)
    radius = max(4.0, 0.18 / canvas.res * canvas.scale)
    draw.ellipse([px - radius, py - radius, px + radius, py + radius], outline=color, width=3)
    tip = canvas.to_pixel(xy[0] + 0.5 * math.cos(yaw), xy[1] + 0.5 * math.sin(yaw))
    draw.line([(px, py), tip], fill=color, width=3)


def draw_episode(
    scene: Scene,
    episode: Episode,
    positions: Sequence[Sequence[float]] | NDArray[np.float64] = (),
    yaws: Sequence[float] = (),
    record: dict[str, Any] | None = None,
    path: str | Path | None = None,
) -> Image.Image:
    """Top-down picture of one episode; written to ``path`` as PNG when given."""
    canvas = _Canvas(scene)
    image = canvas.base_image(scene)
    draw = ImageDraw.Draw(image)
    _draw_rooms(draw, canvas, scene)
    _draw_objects(draw, canvas, scene, {g.object_id for g in episode.goals})
    for x, y in episode.view_points_xy():
        px, py = canvas.to_pixel(x, y)
        draw.ellipse([px - 1.5, py - 1.5, px + 1.5, py + 1.5], fill=(40, 170, 60))
    trajectory = [canvas.to_pixel(float(p[0]), float(p[1])) for p in positions]
    if len(trajectory) > 1:
        draw.line(trajectory, fill=(230, 120, 0), width=3, joint="curve")
    _draw_pose(draw, canvas, habitat_to_world(episode.start_position), episode.start_yaw, (30, 90, 220))
    if len(positions) and len(yaws):
        success = bool(record and record.get("success"))
        end = (float(positions[-1][0]), float(positions[-1][1]))
        _draw_pose(draw, canvas, end, float(yaws[-1]), (20, 160, 40) if success else (210, 30, 30))
    draw.text((6, 6), _title(episode, record), fill=(0, 0, 0))
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        image.save(path)
    return image


def _title(episode: Episode, record: dict[str, Any] | None) -> str:
    text = f"episode {episode.episode_id}  {episode.scene_id}  target: '{episode.object_category}'"
    if record:
        text += (
            f"  success={record.get('success')}  SPL={float(record.get('spl', 0.0)):.2f}"
            f"  steps={record.get('steps')}  stop={record.get('stop_reason')}"
        )
    return text + "   (blue: start, orange: path, green dots: view points, red outline: goals)"
