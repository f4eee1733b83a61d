"""HM3D-OVON-style episodes and the mapping between the 2-D world frame and Habitat's y-up frame.

Habitat positions are ``[x, y, z]`` with ``y`` up and agents facing ``-z``. A 2-D world point ``(X, Y)`` (x east,
y north) on the floor maps to ``[X, 0, -Y]``; this is a proper rotation (north is ``-z``), so headings keep their
sense. A world yaw ``psi`` (counter-clockwise from +X) is a rotation about Habitat's ``+y`` by
``phi = psi - pi/2`` (at ``psi = pi/2`` the agent faces north, Habitat's ``-z``), stored like Habitat's
``start_rotation`` as a quaternion ``[x, y, z, w] = [0, sin(phi/2), 0, cos(phi/2)]``.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Any

from drivenav.jsonstream import JsonObject
from drivenav.validation import Fields

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
    info: JsonObject = field(default_factory=dict)

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


# -- the JSON form ----------------------------------------------------------------------------------------------


def rounded(values: tuple[float, ...]) -> list[float]:
    """Coordinates as episode files store them: 4 decimals (0.1 mm)."""
    return [round(float(v), 4) for v in values]


def goal_to_dict(goal: ObjectGoal) -> JsonObject:
    """A goal instance in the HM3D-OVON / ObjectNav v1 JSON form (``object_id`` as the file's integer)."""
    return {
        "object_id": goal.object_id,
        "object_category": goal.object_category,
        "position": rounded(goal.position),
        "view_points": [
            {"agent_state": {"position": rounded(vp.position), "rotation": rounded(vp.rotation)}, "iou": vp.iou}
            for vp in goal.view_points
        ],
    }


# -- reading the JSON form (episode files, Habitat layouts) with one-line errors naming the field ------------


def parse_vec3(fields: Fields, name: str, value: Any) -> Vec3:
    x, y, z = fields.numbers(value, name, 3)
    return (x, y, z)


QUATERNION_NORM_TOLERANCE = 0.01  # a rotation is a unit quaternion; datasets round their components


def parse_quat(fields: Fields, name: str, value: Any) -> Quat:
    """A rotation ``[x, y, z, w]``: a unit quaternion (within :data:`QUATERNION_NORM_TOLERANCE`; a zero one is no
    rotation)."""
    x, y, z, w = fields.numbers(value, name, 4)
    if abs(math.sqrt(x * x + y * y + z * z + w * w) - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise fields.error(name, "a unit quaternion [x, y, z, w]", list(value))
    return (x, y, z, w)


def parse_identifier(fields: Fields, name: str, value: Any) -> str:
    """A non-empty string; integer ids (as some datasets write them) become strings."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return fields.text(value, name)


def parse_episode(fields: Fields, name: str, item: Any, require_goals: bool = True) -> Episode:
    """One episode; ``require_goals`` False also reads a live run's episode (a target on a robot, no goals)."""
    item = fields.mapping(item, name)
    goals = parse_goals(fields, f"{name}.goals", item.get("goals"), require_goals)
    return parse_episode_with(fields, name, item, goals)


def parse_episode_with(fields: Fields, name: str, item: JsonObject, goals: tuple[ObjectGoal, ...]) -> Episode:
    """An episode whose ``goals`` were read already (a streamed file reads a repeated goals text once)."""
    return Episode(
        episode_id=parse_identifier(fields, f"{name}.episode_id", item.get("episode_id")),
        scene_id=sys.intern(parse_identifier(fields, f"{name}.scene_id", item.get("scene_id"))),
        start_position=parse_vec3(fields, f"{name}.start_position", item.get("start_position")),
        start_rotation=parse_quat(fields, f"{name}.start_rotation", item.get("start_rotation")),
        object_category=sys.intern(parse_identifier(fields, f"{name}.object_category", item.get("object_category"))),
        goals=goals,
        info=parse_info(fields, f"{name}.info", item.get("info", {})),
    )


def parse_goals(fields: Fields, name: str, value: Any, require_goals: bool = True) -> tuple[ObjectGoal, ...]:
    """An episode's ``goals``: at least one unless ``require_goals`` is False."""
    items = fields.sequence(value, name, 1 if require_goals else 0)
    return tuple(parse_goal(fields, f"{name}[{k}]", goal) for k, goal in enumerate(items))


def parse_info(fields: Fields, name: str, value: Any) -> JsonObject:
    """``info``: the keys drivenav reads have their types (distance in metres >= 0, text, true / false); others
    are kept as given."""
    info = fields.mapping(value, name)
    if "geodesic_distance" in info:
        fields.number(info["geodesic_distance"], f"{name}.geodesic_distance", minimum=0.0)
    if "canonical_category" in info:
        fields.text(info["canonical_category"], f"{name}.canonical_category")
    if "synonym" in info:
        fields.choice(info["synonym"], f"{name}.synonym", (True, False), "true or false")
    return info


def parse_goal(fields: Fields, name: str, item: Any) -> ObjectGoal:
    item = fields.mapping(item, name)
    view_points = []
    for k, point in enumerate(fields.sequence(item.get("view_points"), f"{name}.view_points", 1)):
        where = f"{name}.view_points[{k}]"
        state = fields.mapping(fields.mapping(point, where).get("agent_state"), f"{where}.agent_state")
        position = parse_vec3(fields, f"{where}.agent_state.position", state.get("position"))
        rotation = parse_quat(fields, f"{where}.agent_state.rotation", state.get("rotation"))
        view_points.append(ViewPoint(position, rotation, fields.number(point.get("iou", 1.0), f"{where}.iou")))
    return ObjectGoal(
        object_id=fields.integer(item.get("object_id", -1), f"{name}.object_id"),
        object_category=parse_identifier(fields, f"{name}.object_category", item.get("object_category", "object")),
        position=parse_vec3(fields, f"{name}.position", item.get("position")),
        view_points=tuple(view_points),
    )
