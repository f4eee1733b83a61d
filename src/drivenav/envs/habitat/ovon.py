"""HM3D-OVON episodes as a habitat-lab dataset (``OVON-v1``), registered on import (imports habitat-lab).

habitat-lab's ``ObjectNav-v1`` reader rejects HM3D-OVON (view points carry ``radius``; the category maps are
empty), so episodes are read with :func:`~drivenav.envs.habitat.layouts.read_split` and handed to habitat-lab as
its own ``ObjectGoalNavEpisode`` / ``ObjectGoal`` / ``ObjectViewLocation`` records. Each episode's goals include
the instances of its ``children_object_categories``, so habitat-lab's ``DistanceToGoal`` and ``Success`` count
them as HM3D-OVON's success does. Episode ids are the file's own (not re-numbered), scenes are resolved under
``scenes_dir`` as habitat-lab resolves them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from habitat.core.dataset import ALL_SCENES_MASK, Dataset
from habitat.core.registry import registry
from habitat.core.simulator import AgentState
from habitat.tasks.nav.object_nav_task import ObjectGoal, ObjectGoalNavEpisode, ObjectViewLocation

from drivenav.envs.habitat.benchmarks import OVON
from drivenav.envs.habitat.layouts import read_split, scene_name, scene_path
from drivenav.episode import Episode
from drivenav.episode import ObjectGoal as DrivenavGoal

if TYPE_CHECKING:
    from omegaconf import DictConfig

DATASET_TYPE = "OVON-v1"


def _goal(goal: DrivenavGoal) -> Any:
    views = [ObjectViewLocation(AgentState(list(vp.position), list(vp.rotation)), vp.iou) for vp in goal.view_points]
    return ObjectGoal(
        object_id=str(goal.object_id),
        object_category=goal.object_category,
        position=list(goal.position),
        view_points=views,
    )


def habitat_episode(episode: Episode, scenes_dir: str | None) -> Any:
    """A drivenav episode as habitat-lab's ``ObjectGoalNavEpisode``."""
    info = dict(episode.info)
    return ObjectGoalNavEpisode(
        episode_id=episode.episode_id,
        scene_id=scene_path(episode.scene_id, scenes_dir),
        scene_dataset_config=str(info.get("scene_dataset_config", "default")),
        start_position=list(episode.start_position),
        start_rotation=list(episode.start_rotation),
        object_category=episode.object_category,
        goals=[_goal(goal) for goal in episode.goals],
        info=info,
    )


@registry.register_dataset(name=DATASET_TYPE)
class OVONDatasetV1(Dataset):  # type: ignore[misc]
    """HM3D-OVON's split layout (``{split}/{split}.json.gz`` and ``content/<scene>.json.gz``)."""

    def __init__(self, config: DictConfig | None = None) -> None:
        self.episodes: list[Any] = []
        if config is None:
            return
        split_file = Path(config.data_path.format(split=config.split))
        scenes = set(config.content_scenes)
        for episode in read_split(split_file, OVON):
            if ALL_SCENES_MASK in scenes or scene_name(episode.scene_id) in scenes:
                self.episodes.append(habitat_episode(episode, config.scenes_dir))
