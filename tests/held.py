"""Episodes as the Habitat layouts hold them, for the tests that export drivenav's episodes and read them back."""

from __future__ import annotations

from dataclasses import replace

from drivenav.envs.habitat.layouts import HABITAT_DIGITS
from drivenav.episode import Episode, ObjectGoal, Quat, Vec3, coordinates


def as_held(episode: Episode) -> Episode:
    """``episode`` as a Habitat layout holds it: ``write_split`` writes coordinates to habitat-lab's
    :data:`HABITAT_DIGITS` decimals (drivenav's own files keep every digit), so an episode read back from an export
    is this one."""

    def vec(values: Vec3) -> Vec3:
        x, y, z = coordinates(values, HABITAT_DIGITS)
        return x, y, z

    def quat(values: Quat) -> Quat:
        a, b, c, d = coordinates(values, HABITAT_DIGITS)
        return a, b, c, d

    def goal(g: ObjectGoal) -> ObjectGoal:
        points = tuple(replace(vp, position=vec(vp.position), rotation=quat(vp.rotation)) for vp in g.view_points)
        return replace(g, position=vec(g.position), view_points=points)

    goals = tuple(goal(g) for g in episode.goals)
    return replace(
        episode, start_position=vec(episode.start_position), start_rotation=quat(episode.start_rotation), goals=goals
    )
