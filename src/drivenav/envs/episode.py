"""HM3D-OVON-style episodes and the mapping between the 2-D world frame and Habitat's y-up frame.

Habitat positions are ``[x, y, z]`` with ``y`` up and agents facing ``-z``. A 2-D world point ``(X, Y)`` (x east,
y north) on the floor maps to ``[X, 0, -Y]``; this is a proper rotation (north is ``-z``), so headings keep their
sense. A world yaw ``psi`` (counter-clockwise from +X) is a rotation about Habitat's ``+y`` by
``phi = psi - pi/2`` (at ``psi = pi/2`` the agent faces north, Habitat's ``-z``), stored like Habitat's
``start_rotation`` as a quaternion ``[x, y, z, w] = [0, sin(phi/2), 0, cos(phi/2)]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def world_to_habitat(x: float, y: float, height: float = 0.0) -> Vec3:
    """2-D world point to a Habitat position (y up)."""
    return (float(x), float(height), float(-y))


def habitat_to_world(position: Vec3 | list[float]) -> tuple[float, float]:
    """Habitat position to a 2-D world point (height dropped)."""
    return float(position[0]), float(-position[2])


def yaw_to_quaternion(yaw: float) -> Quat:
    """World yaw (radians, counter-clockwise from +x) to a Habitat rotation quaternion ``[x, y, z, w]``."""
    phi = yaw - math.pi / 2.0
    return (0.0, math.sin(phi / 2.0), 0.0, math.cos(phi / 2.0))


def quaternion_to_yaw(q: Quat | list[float]) -> float:
    """Habitat rotation quaternion ``[x, y, z, w]`` (rotation about +y) to a world yaw in ``(-pi, pi]``."""
    phi = 2.0 * math.atan2(q[1], q[3])
    yaw = math.remainder(phi + math.pi / 2.0, 2.0 * math.pi)
    return math.pi if yaw == -math.pi else yaw


@dataclass(frozen=True)
class ViewPoint:
    """A navigable position within 1.0 m of a goal object from which it is visible (Habitat view point)."""

    position: Vec3
    rotation: Quat
    iou: float = 1.0

    @property
    def xy(self) -> tuple[float, float]:
        return habitat_to_world(self.position)


@dataclass(frozen=True)
class ObjectGoal:
    """One instance of the target category and its view points."""

    object_id: int
    object_category: str
    position: Vec3
    view_points: tuple[ViewPoint, ...]


@dataclass(frozen=True)
class Episode:
    """An ObjectNav episode in the HM3D-OVON schema.

    ``object_category`` is the text given to the agent (possibly a synonym); ``info`` holds
    ``geodesic_distance`` (metres, start to the nearest view point), ``canonical_category`` and ``synonym``.
    """

    episode_id: str
    scene_id: str
    start_position: Vec3
    start_rotation: Quat
    object_category: str
    goals: tuple[ObjectGoal, ...]
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def start_xy(self) -> tuple[float, float]:
        return habitat_to_world(self.start_position)

    @property
    def start_yaw(self) -> float:
        return quaternion_to_yaw(self.start_rotation)

    @property
    def geodesic_distance(self) -> float:
        return float(self.info.get("geodesic_distance", float("nan")))

    def view_points_xy(self) -> list[tuple[float, float]]:
        """All goals' view points as 2-D world points."""
        return [vp.xy for goal in self.goals for vp in goal.view_points]
