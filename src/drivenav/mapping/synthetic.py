"""A tiny analytic depth renderer (axis-aligned boxes on a flat floor) for mapping tests and benchmarks.

It follows the mapper's camera model: a level pinhole camera at ``camera_height`` looking along the
agent's heading; pixel ``(v, u)`` looks along ``(1, (cx - u) / fx, (cy - v) / fy)`` in (forward, left, up)
camera axes, so the ray parameter of a hit is its z-depth. Depth is clipped to ``[min_depth, max_depth]``
like Habitat's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.types import CameraIntrinsics, Pose


@dataclass(frozen=True)
class Box3:
    """An axis-aligned box in the episode frame: ``x`` and ``y`` spans on the floor, ``z`` the height span."""

    x: tuple[float, float]
    y: tuple[float, float]
    z: tuple[float, float] = (0.0, 2.5)


def wall(x0: float, y0: float, x1: float, y1: float, thickness: float = 0.1, height: float = 2.5) -> Box3:
    """A full-height wall along an axis-parallel segment, ``thickness`` wide and centred on the segment."""
    half = thickness / 2.0
    return Box3((min(x0, x1) - half, max(x0, x1) + half), (min(y0, y1) - half, max(y0, y1) + half), (0.0, height))


def room(x0: float, y0: float, x1: float, y1: float, door_east: tuple[float, float] | None = None) -> list[Box3]:
    """The four walls of a rectangular room; ``door_east`` = (y_lo, y_hi) leaves a gap in the east wall."""
    walls = [wall(x0, y0, x1, y0), wall(x0, y1, x1, y1), wall(x0, y0, x0, y1)]
    if door_east is None:
        return [*walls, wall(x1, y0, x1, y1)]
    return [*walls, wall(x1, y0, x1, door_east[0]), wall(x1, door_east[1], x1, y1)]


@dataclass(frozen=True)
class BoxWorld:
    """Boxes standing in an otherwise empty world with an infinite floor at height 0."""

    boxes: tuple[Box3, ...]

    def render(
        self,
        pose: Pose,
        intrinsics: CameraIntrinsics,
        camera_height: float = 0.88,
        depth_range: tuple[float, float] = (0.5, 5.0),
    ) -> NDArray[np.float32]:
        """The clipped z-depth image ``(H, W)`` seen from ``pose``."""
        v, u = np.mgrid[0 : intrinsics.height, 0 : intrinsics.width].astype(np.float64)
        left = (intrinsics.cx - u) / intrinsics.fx
        up = (intrinsics.cy - v) / intrinsics.fy
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        direction = (c - s * left, s + c * left, up)
        origin = (pose.x, pose.y, camera_height)
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(up < 0.0, camera_height / -up, np.inf)
            for box in self.boxes:
                depth = np.minimum(depth, _slab_hit(origin, direction, box))
        return np.clip(depth, *depth_range).astype(np.float32)


def _slab_hit(
    origin: tuple[float, float, float], direction: tuple[NDArray[np.float64], ...], box: Box3
) -> NDArray[np.float64]:
    """Ray parameter of the first hit with ``box`` (inf where missed), by the slab method."""
    near = np.zeros_like(direction[0])
    far = np.full_like(direction[0], np.inf)
    for o, d, (lo, hi) in zip(origin, direction, (box.x, box.y, box.z), strict=True):
        t0, t1 = (lo - o) / d, (hi - o) / d
        near = np.maximum(near, np.minimum(t0, t1))
        far = np.minimum(far, np.maximum(t0, t1))
    return np.where((near <= far) & np.isfinite(near), near, np.inf)
