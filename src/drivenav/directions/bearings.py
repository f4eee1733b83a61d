"""Path-induced bearings (Sec. IV-A b): the local directional point p_i is the first crossing of frontier i's FMM
path, walked from the robot outward, with the robot-centred circle of radius R_e."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit

TWO_PI = 2.0 * math.pi

Point = Sequence[float] | NDArray[np.float64]  # a world (x, y)


def normalize_angle(angle: float) -> float:
    """Map an angle in radians to ``[0, 2 pi)``."""
    wrapped = math.fmod(angle, TWO_PI)
    if wrapped < 0.0:
        wrapped += TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


def bearing_to(origin: Point, point: Point) -> float:
    """Bearing in ``[0, 2 pi)`` from ``origin`` to ``point``, counter-clockwise from +x."""
    return normalize_angle(math.atan2(point[1] - origin[1], point[0] - origin[0]))


@jit("UniTuple(f8, 2)(f8[:, ::1], f8, f8, f8)")
def _crossing_kernel(path: NDArray[np.float64], cx: float, cy: float, radius: float) -> tuple[float, float]:
    r2 = radius * radius
    px, py = path[0, 0] - cx, path[0, 1] - cy
    if px * px + py * py >= r2:
        return path[0, 0], path[0, 1]
    for k in range(1, path.shape[0]):
        qx, qy = path[k, 0] - cx, path[k, 1] - cy
        if qx * qx + qy * qy >= r2:
            # |p + t d|^2 = R^2 with |p| < R <= |p + d|: the larger root lies in (0, 1].
            dx, dy = qx - px, qy - py
            a = dx * dx + dy * dy
            b = px * dx + py * dy
            c = px * px + py * py - r2
            t = (-b + math.sqrt(max(b * b - a * c, 0.0))) / a
            t = min(max(t, 0.0), 1.0)
            return cx + px + t * dx, cy + py + t * dy
        px, py = qx, qy
    return path[-1, 0], path[-1, 1]


def circle_crossing(path: NDArray[np.float64], center: Point, radius: float) -> tuple[float, float]:
    """The first point where the polyline ``path`` ``(N, 2)`` reaches distance ``radius`` from ``center``.

    Exact segment/circle intersection on the first segment that ends on or outside the circle; if the whole
    path stays inside, its last point.
    """
    pts = np.ascontiguousarray(path, dtype=np.float64).reshape(-1, 2)
    x, y = _crossing_kernel(pts, float(center[0]), float(center[1]), float(radius))
    return float(x), float(y)
