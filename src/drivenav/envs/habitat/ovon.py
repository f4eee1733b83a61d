"""HM3D-OVON episodes as a habitat-lab dataset, registered on import as ``drivenav-OVON-v1`` (imports habitat-lab).

habitat-lab's ``ObjectNav-v1`` reader rejects HM3D-OVON (view points carry ``radius``; the category maps are
empty), so episodes are read with :func:`~drivenav.envs.habitat.layouts.read_split` and handed to habitat-lab as
its own ``ObjectGoalNavEpisode`` / ``ObjectGoal`` / ``ObjectViewLocation`` records. Each episode's goals include
the instances of its ``children_object_categories``, so habitat-lab's ``DistanceToGoal`` and ``Success`` count
them as HM3D-OVON's success does. Episode ids are the file's own (not re-numbered), scenes are resolved under
``scenes_dir`` as habitat-lab resolves them.

The name is drivenav's own: HM3D-OVON's code registers its ``OVONDatasetV1`` as ``OVON-v1``, and a run whose
``--habitat-plugin`` registers that name reads the split with it (:func:`dataset_type`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from habitat.core.dataset import ALL_SCENES_MASK, Dataset
from habitat.core.registry import registry
from habitat.core.simulator import AgentState
from habitat.tasks.nav.object_nav_task import ObjectGoal, ObjectGoalNavEpisode, ObjectViewLocation

from drivenav.envs.habitat.benchmarks import DATASET_TYPES, OVON, OVON_DATASET_TYPE
from drivenav.envs.habitat.layouts import read_split, scene_name, scene_path
from drivenav.episode import Episode
from drivenav.episode import ObjectGoal as DrivenavGoal

if TYPE_CHECKING:
    from omegaconf import DictConfig

DATASET_TYPE = DATASET_TYPES[OVON]


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
    return ObjectGoalNavEpisode(
        episode_id=episode.episode_id,
        scene_id=scene_path(episode.scene_id, scenes_dir),
        scene_dataset_config=episode.scene_dataset_config,
        start_position=list(episode.start_position),
        start_rotation=list(episode.start_rotation),
        object_category=episode.object_category,
        goals=[_goal(goal) for goal in episode.goals],
        info=dict(episode.info),
    )


@registry.register_dataset(name=DATASET_TYPE)
class OVONDataset(Dataset):  # type: ignore[misc]
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


def dataset_type(layout: str) -> str:
    """The dataset type a run of ``layout`` reads its split with: HM3D-OVON's own ``OVON-v1`` where a plugin has
    registered it, else drivenav's."""
    if layout == OVON and registry.get_dataset(OVON_DATASET_TYPE) is not None:
        return OVON_DATASET_TYPE
    return DATASET_TYPES[layout]
