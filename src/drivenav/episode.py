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
DEFAULT_SCENE_DATASET = "default"  # habitat-lab's Episode.scene_dataset_config when a file names none
CHILDREN = "children_object_categories"
HALF_STOREY = 1.2
"""Metres: a goal view point this near a height is on that height's floor. Half of 2.4 m, the least floor-to-floor
height the embedded buildings assume: a view point a floor up or down is never within it, one on the floor (a step
above or below it at most) always is. It counts floor changes in episodes without floor information (HM3D's; ``drivenav
episodes stats``) and gives the oracle reasoner its floor answer."""


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
    """A navigable position within 1.0 m of a goal object from which it is visible (Habitat view point).

    ``radius`` is HM3D-OVON's: the distance from the object at which its generator sampled the pose (metres), kept
    as a file gives it; ``None`` where a file has none (drivenav's own episodes, ObjectNav v1).
    """

    position: Vec3
    rotation: Quat
    iou: float = 1.0
    radius: float | None = None

    @property
    def xy(self) -> tuple[float, float]:
        return habitat_to_world(self.position)

    @property
    def height(self) -> float:
        """Height above the scene's ground floor (Habitat's ``y``)."""
        return float(self.position[1])


@dataclass(frozen=True)
class ObjectGoal:
    """One instance of the target category and its view points.

    ``object_id`` is the instance number, what a semantic sensor shows of the object (``target_seen`` counts those
    pixels); -1 where a file gives none. HM3D-OVON writes ids as text ``"<category>_<n>"`` (its own loader takes
    ``n``): ``dataset_id`` keeps a file's text where it is not ``"<object_category>_<object_id>"``, the form
    :func:`habitat_object_id` writes, so the file's id is written back as it was.
    """

    object_id: int
    object_category: str
    position: Vec3
    view_points: tuple[ViewPoint, ...]
    dataset_id: str | None = None


@dataclass(frozen=True)
class Episode:
    """An ObjectNav episode in the HM3D-OVON schema.

    ``object_category`` is the text given to the agent (possibly a synonym); ``info`` holds
    ``geodesic_distance`` (metres, start to the nearest view point), ``canonical_category`` and ``synonym``.
    ``goals`` are every instance that counts for success: HM3D-OVON's include those of the
    ``children_object_categories`` (its sub-categories present in the scene, each goal keeping its own category).
    ``scene_dataset_config`` is habitat-sim's scene dataset of the scene (``"default"``: none named).
    """

    episode_id: str
    scene_id: str
    start_position: Vec3
    start_rotation: Quat
    object_category: str
    goals: tuple[ObjectGoal, ...]
    info: JsonObject = field(default_factory=dict)
    scene_dataset_config: str = DEFAULT_SCENE_DATASET
    children_object_categories: tuple[str, ...] = ()

    @property
    def start_xy(self) -> tuple[float, float]:
        return habitat_to_world(self.start_position)

    @property
    def start_height(self) -> float:
        """Height of the start above the scene's ground floor (Habitat's ``y``): 0 on a one-floor scene."""
        return float(self.start_position[1])

    @property
    def start_yaw(self) -> float:
        return quaternion_to_yaw(self.start_rotation)

    @property
    def geodesic_distance(self) -> float:
        return float(self.info.get("geodesic_distance", float("nan")))

    def view_points_xy(self) -> list[tuple[float, float]]:
        """All goals' view points as 2-D world points."""
        return [vp.xy for goal in self.goals for vp in goal.view_points]

    def view_points_xyz(self) -> list[tuple[float, float, float]]:
        """All goals' view points as world points with their heights."""
        return [(*vp.xy, vp.height) for goal in self.goals for vp in goal.view_points]


# -- the JSON form ----------------------------------------------------------------------------------------------


def coordinates(values: tuple[float, ...], digits: int | None = None) -> list[float]:
    """Coordinates as episode files store them: exactly (JSON writes the shortest text that reads back as the same
    float), so an episode read from its file is the episode that ran; or to ``digits`` decimals where a format
    asks for it (Habitat's layouts: :data:`~drivenav.envs.habitat.layouts.HABITAT_DIGITS`)."""
    return [float(v) if digits is None else round(float(v), digits) for v in values]


def habitat_object_id(goal: ObjectGoal) -> str:
    """A goal's id in HM3D-OVON's text form: the file's own where it had one, else ``"<category>_<n>"``."""
    return goal.dataset_id if goal.dataset_id is not None else f"{goal.object_category}_{goal.object_id}"


def view_point_to_dict(point: ViewPoint, digits: int | None = None) -> JsonObject:
    """A view point in the JSON form (``radius`` where it has one), coordinates exact or to ``digits`` decimals."""
    state = {"position": coordinates(point.position, digits), "rotation": coordinates(point.rotation, digits)}
    item: JsonObject = {"agent_state": state, "iou": point.iou}
    if point.radius is not None:
        item["radius"] = point.radius
    return item


def goal_to_dict(goal: ObjectGoal) -> JsonObject:
    """A goal instance in drivenav's JSON form: ObjectNav v1's, ``object_id`` the integer (or the file's own text,
    where a dataset gave one), view points with ``radius`` where they have one."""
    return {
        "object_id": goal.dataset_id if goal.dataset_id is not None else goal.object_id,
        "object_category": goal.object_category,
        "position": coordinates(goal.position),
        "view_points": [view_point_to_dict(vp) for vp in goal.view_points],
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
        scene_dataset_config=parse_scene_dataset(
            fields, f"{name}.scene_dataset_config", item.get("scene_dataset_config")
        ),
        children_object_categories=tuple(fields.texts(item.get(CHILDREN) or [], f"{name}.{CHILDREN}")),
    )


def parse_scene_dataset(fields: Fields, name: str, value: Any) -> str:
    """An episode's ``scene_dataset_config``: a path, or habitat-lab's ``"default"`` where none is given."""
    return DEFAULT_SCENE_DATASET if value is None else sys.intern(fields.text(value, name))


def episode_extras(episode: Episode) -> JsonObject:
    """The keys of an episode's JSON form that only some datasets have, where they differ from the defaults
    (drivenav's own episodes have none, and their files stay as they were)."""
    extras: JsonObject = {}
    if episode.scene_dataset_config != DEFAULT_SCENE_DATASET:
        extras["scene_dataset_config"] = episode.scene_dataset_config
    if episode.children_object_categories:
        extras[CHILDREN] = list(episode.children_object_categories)
    return extras


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
    view_points = [
        parse_view_point(fields, f"{name}.view_points[{k}]", point)
        for k, point in enumerate(fields.sequence(item.get("view_points"), f"{name}.view_points", 1))
    ]
    category = parse_identifier(fields, f"{name}.object_category", item.get("object_category", "object"))
    object_id, dataset_id = parse_object_id(fields, f"{name}.object_id", item.get("object_id", -1), category)
    return ObjectGoal(
        object_id=object_id,
        object_category=category,
        position=parse_vec3(fields, f"{name}.position", item.get("position")),
        view_points=tuple(view_points),
        dataset_id=dataset_id,
    )


def parse_view_point(fields: Fields, name: str, point: Any) -> ViewPoint:
    state = fields.mapping(fields.mapping(point, name).get("agent_state"), f"{name}.agent_state")
    radius = point.get("radius")
    return ViewPoint(
        position=parse_vec3(fields, f"{name}.agent_state.position", state.get("position")),
        rotation=parse_quat(fields, f"{name}.agent_state.rotation", state.get("rotation")),
        iou=fields.number(point.get("iou", 1.0), f"{name}.iou"),
        radius=None if radius is None else fields.number(radius, f"{name}.radius", minimum=0.0),
    )


MAX_ID_DIGITS = 18
"""The most digits an instance number may have (a longer one is no instance: -1)."""


def parse_object_id(fields: Fields, name: str, value: Any, category: str) -> tuple[int, str | None]:
    """A goal's ``object_id``: an integer, or text ending in ``_<n>`` or all digits (HM3D-OVON's
    ``"<category>_<n>"``), whose ``n`` is the instance number; other text is kept with the number -1 (no
    instance). Returns the number and the text where :func:`habitat_object_id` would not write it back as it was."""
    if isinstance(value, int) and not isinstance(value, bool):
        return value, None
    if not isinstance(value, str) or not value.strip():
        raise fields.error(name, "an integer, or a text id such as 'chair_3'", value)
    number = value.rsplit("_", 1)[-1]
    instance = int(number) if number.isascii() and number.isdigit() and len(number) <= MAX_ID_DIGITS else -1
    return instance, None if value == f"{category}_{instance}" else value
