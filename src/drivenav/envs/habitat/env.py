"""A Habitat world: drivenav's :class:`~drivenav.envs.base.Env` over habitat-lab's ``habitat.Env``.

habitat-lab's task, sensors and measures do the work: the agent steps by action name (habitat-lab's integer
indices follow the config's order), observations are converted by :mod:`.observations`, and the metrics are
habitat-lab's own ``success``, ``spl``, ``distance_to_goal`` and ``collisions``; path length is the executed
translation in three dimensions (as habitat-lab's ``SPL`` sums it), the start distance habitat-lab's
``distance_to_goal`` at reset. The world frame is Habitat's floor plane as drivenav's 2-D map frame
(:mod:`drivenav.episode`), with Habitat's ``y`` as the pose's height.

The agent's pose is the simulator's agent state relative to the episode start, in float64: exactly what the
noise-free GPS and compass report, without their float32 rounding (~1e-7 m), which alone can flip a map cell
or a sight line and make two runs of one episode differ. GPS and compass are still read and checked against it
every step (:func:`check_gps_compass`), so a changed frame or sign convention stops the episode. ObjectNav's GPS is
2-D, so the height comes from the agent state alone: the pose's height is the agent's height above where the
simulator placed it at reset (an episode file's start height may lie a little above the floor, as HM3D's do).

For the oracle, ``geodesic`` ground truth comes from the simulator: its geodesic distance to the goals' view
points and its path finder's step (with or without sliding, as the config's ``allow_sliding`` says), both in three
dimensions, so that the oracle climbs and descends stairs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav import metrics
from drivenav.envs.base import EpisodeMeasures, episode_pose, measured, shows_goal
from drivenav.envs.habitat.config import habitat_config
from drivenav.envs.habitat.observations import to_observation
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.episode import Episode, habitat_to_world, quaternion_to_yaw, world_to_habitat
from drivenav.grid import wrap_angle
from drivenav.types import GEODESIC, SEMANTIC, Action, GroundTruth, Observation, Pose, SimConfig

if TYPE_CHECKING:
    from drivenav.envs.habitat.spec import HabitatSpec

ACTION_NAMES = {
    Action.STOP: "stop",
    Action.MOVE_FORWARD: "move_forward",
    Action.TURN_LEFT: "turn_left",
    Action.TURN_RIGHT: "turn_right",
}
POSE_CHECK = 1e-3  # metres / radians: GPS and compass against the agent state (float32 sensors read ~1e-6)
COLLISION_EPSILON = 1e-5  # m^2: a step collided when its squared 3-D length falls short of the intended one by more


class HabitatEpisode(Protocol):
    """What drivenav reads of one of habitat-lab's episodes (``habitat.core.dataset.Episode``)."""

    start_position: Any
    start_rotation: Sequence[float]


def habitat_pose(position: Any, rotation: Sequence[float]) -> Pose:
    """A Habitat position and rotation quaternion ``[x, y, z, w]`` as a world-frame pose (its height Habitat's
    ``y``)."""
    point = np.asarray(position, dtype=np.float64)
    x, y = habitat_to_world(list(point))
    return Pose(x, y, quaternion_to_yaw([float(v) for v in rotation]), float(point[1]))


def agent_pose(state: Any) -> Pose:
    """A habitat-sim agent state (position, ``quaternion.quaternion`` rotation) as a world-frame pose."""
    q = state.rotation
    return habitat_pose(state.position, (q.x, q.y, q.z, q.w))


@dataclass(frozen=True)
class _SimGeodesic:
    """The simulator's geodesic ground truth for one episode (the oracle's :class:`~drivenav.types.GeodesicOracle`)."""

    sim: Any
    episode: Any
    targets: list[Any]  # the goals' view point positions, as habitat-lab's DistanceToGoal measures to
    start_pose: Pose
    step: float
    sliding: bool

    def distance(self, pose: Pose) -> float:
        position = list(world_to_habitat(pose.x, pose.y, pose.z))
        return float(self.sim.geodesic_distance(position, self.targets, self.episode))

    def forward(self, pose: Pose) -> tuple[Pose, bool]:
        x, y, yaw = pose.x, pose.y, pose.yaw
        start = np.array(world_to_habitat(x, y, pose.z))
        end = np.array(world_to_habitat(x + self.step * math.cos(yaw), y + self.step * math.sin(yaw), pose.z))
        finder = self.sim.pathfinder
        reached = np.asarray(finder.try_step(start, end) if self.sliding else finder.try_step_no_sliding(start, end))
        nx, ny = habitat_to_world(list(reached))
        arrived = Pose(nx, ny, yaw, float(reached[1]))
        return arrived, _collided(pose, arrived, self.step)

    @property
    def goal_heights(self) -> tuple[float, ...]:
        return tuple(sorted({float(position[1]) for position in self.targets}))  # habitat's y is up


def _collided(start: Pose, reached: Pose, step: float) -> bool:
    """habitat-sim's collision rule (``ObjectControls``): a forward step of ``step`` metres collided when the squared
    3-D distance it moved falls short of the intended one by more than :data:`COLLISION_EPSILON`, so that a step up
    or down the stairs (longer in 3-D than in plan) is none."""
    moved = (reached.x - start.x) ** 2 + (reached.y - start.y) ** 2 + (reached.z - start.z) ** 2
    return moved + COLLISION_EPSILON < step * step


class HabitatEnv:
    """One ``habitat.Env`` over a benchmark split; episodes are looked up by drivenav's episode id."""

    def __init__(self, spec: HabitatSpec, sim: SimConfig) -> None:
        spec.import_plugins()  # first: a plugin may have to prepare habitat-lab's import

        import habitat

        self._config = sim
        self._habitat_config = habitat_config(spec, sim)  # also registers drivenav's HM3D-OVON dataset type
        dataset = habitat.make_dataset(
            self._habitat_config.habitat.dataset.type, config=self._habitat_config.habitat.dataset
        )
        for found in dataset.episodes:
            found.scene_dataset_config = _under_data_dir(found.scene_dataset_config, spec.data_dir)
        self._env = habitat.Env(self._habitat_config, dataset)
        self._by_id = _index(spec.episodes(), list(self._env.episodes))
        depth_sensor = self._habitat_config.habitat.simulator.agents.main_agent.sim_sensors.depth_sensor
        self._normalized = bool(depth_sensor.normalize_depth)
        self._sliding = bool(self._habitat_config.habitat.simulator.habitat_sim_v0.allow_sliding)
        self._steps = 0
        self._positions: list[tuple[float, float, float]] = []
        self._start_distance = math.nan
        self._start_pose = Pose(0.0, 0.0, 0.0)
        self._semantic = spec.semantic
        self._goal_ids: NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self._target_seen = False

    @property
    def config(self) -> SimConfig:
        return self._config

    @property
    def habitat_env(self) -> Any:
        """The wrapped ``habitat.Env``."""
        return self._env

    def reset(self, episode: Episode) -> Observation:
        found = self._by_id.get(episode.episode_id)
        if found is None:
            raise ValueError(f"episode {episode.episode_id} is not in this Habitat split")
        self._env.current_episode = found
        observations = self._env.reset()
        placed = self.world_pose()  # the start's height: where the simulator stands the agent
        self._start_pose = replace(habitat_pose(found.start_position, found.start_rotation), z=placed.z)
        self._steps = 0
        self._positions = [self._xyz()]
        self._start_distance = float(self._env.get_metrics()["distance_to_goal"])
        self._goal_ids = np.array([goal.object_id for goal in episode.goals], dtype=np.int64)
        self._target_seen = False
        return self._observe(observations, collided=False)

    def step(self, action: Action) -> Observation:
        observations = self._env.step(ACTION_NAMES[Action(action)])
        self._steps += 1
        self._positions.append(self._xyz())
        return self._observe(observations, collided=bool(self._env.sim.previous_step_collided))

    def world_pose(self) -> Pose:
        return agent_pose(self._env.sim.get_agent_state())

    def measures(self) -> EpisodeMeasures:
        found = self._env.get_metrics()
        return measured(
            success=bool(found["success"]),
            spl=float(found["spl"]),
            distance_to_goal=float(found["distance_to_goal"]),
            path_length=metrics.path_length(np.asarray(self._positions)),
            geodesic_distance=self._start_distance,
            collisions=int(found["collisions"]["count"]),
            target_seen=self._target_seen if self._semantic else None,
        )

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        """``geodesic`` from the simulator; ``semantic`` (with a semantic sensor): the scene's instance labels from
        its semantic annotations, and drivenav's category vocabulary."""
        labels = self._labels() if SEMANTIC in kinds and self._semantic else None
        geodesic = self._geodesic() if GEODESIC in kinds else None
        return GroundTruth(labels, VOCABULARY if labels is not None else None, geodesic)

    def _labels(self) -> dict[int, str]:
        objects = self._env.sim.semantic_annotations().objects
        return {int(obj.semantic_id): str(obj.category.name()) for obj in objects if obj is not None}

    def _geodesic(self) -> _SimGeodesic:
        episode = self._env.current_episode
        targets = [vp.agent_state.position for goal in episode.goals for vp in goal.view_points]
        return _SimGeodesic(self._env.sim, episode, targets, self._start_pose, self._config.forward_step, self._sliding)

    def close(self) -> None:
        self._env.close()

    def _xyz(self) -> tuple[float, float, float]:
        pose = self.world_pose()
        return pose.x, pose.y, pose.z

    def _observe(self, observations: Any, collided: bool) -> Observation:
        observation = to_observation(observations, self._config, self._steps, collided, self._normalized)
        pose = episode_pose(self._start_pose, self.world_pose())  # the simulator's state, float64
        check_gps_compass(observation.pose, pose)
        self._target_seen = self._target_seen or shows_goal(observation, self._goal_ids)
        return replace(observation, pose=pose)


def check_gps_compass(sensed: Pose, pose: Pose) -> None:
    """GPS and compass must report the pose the simulator holds (they are noise-free in ObjectNav); a
    disagreement means a frame or sign convention changed, and every map built from it would be wrong. Only the
    plane is checked: ObjectNav's GPS reads no height."""
    if (
        math.hypot(sensed.x - pose.x, sensed.y - pose.y) > POSE_CHECK
        or abs(wrap_angle(sensed.yaw - pose.yaw)) > POSE_CHECK
    ):
        raise ValueError(f"GPS/compass give {sensed}, the simulator's agent state {pose} (episode frame)")


def _under_data_dir(path: str, data_dir: str) -> str:
    """An episode's ``scene_dataset_config`` written relative to habitat's ``data/`` folder (``./data/...``, as the
    released datasets write it), resolved under ``--data-dir`` instead of the working directory."""
    for prefix in ("./data/", "data/"):
        if path.startswith(prefix):
            return f"{data_dir.rstrip('/')}/{path[len(prefix) :]}"
    return path


def _index(ours: list[Episode], theirs: list[Any]) -> dict[str, HabitatEpisode]:
    """drivenav's episode ids -> habitat-lab's episodes, paired in reading order and checked (scene basename and
    start position must agree, so a reader that ordered them differently fails here, not in the metrics)."""
    if len(ours) != len(theirs):
        raise ValueError(f"habitat-lab read {len(theirs)} episodes of the split, drivenav {len(ours)}")
    for mine, found in zip(ours, theirs, strict=True):
        same_start = np.allclose(mine.start_position, np.asarray(found.start_position, dtype=np.float64), atol=1e-6)
        if not (same_start and found.scene_id.endswith(mine.scene_id.split("/")[-1])):
            raise ValueError(f"episode {mine.episode_id}: habitat-lab's reader gives another episode in its place")
    return {mine.episode_id: found for mine, found in zip(ours, theirs, strict=True)}
