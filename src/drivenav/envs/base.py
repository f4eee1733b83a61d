"""The world protocol: what the runner needs from the embedded simulator, Habitat or a robot bridge.

A world is built in each worker process from a picklable :class:`EnvSpec`. It moves the agent, renders, and owns
its measures: at the end of an episode it reports the Habitat metrics it can compute (:class:`EpisodeMeasures`;
``None`` where it has no ground truth, never 0). Ground truth for agents (:class:`~drivenav.types.GroundTruth`)
is opt-in: a world lists what it can provide, an agent what it needs, and the runner hands over only that.
"""

from __future__ import annotations

import math
from dataclasses import Field, dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import wrap_angle
from drivenav.instances import count_pixels_of
from drivenav.types import Action, GroundTruth, Observation, Pose, SimConfig

if TYPE_CHECKING:
    from drivenav.episode import Episode


@dataclass(frozen=True)
class EpisodeMeasures:
    """The world's metrics for one finished episode (Habitat's measure names); ``None``: not measurable here.

    ``target_seen`` says whether a goal instance was clearly in view at some step (ground truth, used only to
    tell a missed target from a target never seen in the failure analysis).
    """

    success: int | None = None
    spl: float | None = None
    distance_to_goal: float | None = None
    path_length: float | None = None
    geodesic_distance: float | None = None
    collisions: int | None = None
    target_seen: bool | None = None


def measured(
    *,
    success: bool,
    spl: float,
    distance_to_goal: float,
    path_length: float,
    geodesic_distance: float,
    collisions: int,
    target_seen: bool | None,
) -> EpisodeMeasures:
    """A world's raw metrics as every world reports them: distances to 0.1 mm, SPL to 1e-6, a non-finite
    distance (no path to the goal) or SPL as ``None``."""

    def distance(value: float) -> float | None:
        return round(value, 4) if math.isfinite(value) else None

    return EpisodeMeasures(
        success=int(success),
        spl=round(spl, 6) if math.isfinite(spl) else None,
        distance_to_goal=distance(distance_to_goal),
        path_length=round(path_length, 4),
        geodesic_distance=distance(geodesic_distance),
        collisions=collisions,
        target_seen=target_seen,
    )


def episode_pose(start: Pose, pose: Pose) -> Pose:
    """A world-frame ``pose`` in the episode frame of a world whose episode started at ``start`` (what every
    world reports as :attr:`Observation.pose`), yaw in ``(-pi, pi]``, height relative to the start's."""
    local = start.inverse().compose(pose)
    return Pose(local.x, local.y, wrap_angle(local.yaw), local.z)


class Env(Protocol):
    """What every world implements: the embedded simulator, Habitat, a robot bridge."""

    @property
    def config(self) -> SimConfig:
        """The sensor and body settings the world runs with."""
        ...

    def reset(self, episode: Episode) -> Observation:
        """Start ``episode``: place the agent and return the first observation."""
        ...

    def step(self, action: Action) -> Observation:
        """Apply one action (STOP included: it ends the episode for the measures)."""
        ...

    def world_pose(self) -> Pose:
        """The agent's pose in the world's own frame (scene map, Habitat's, the robot's odometry frame)."""
        ...

    def measures(self) -> EpisodeMeasures:
        """The metrics of the episode so far (called once, after its last step)."""
        ...

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        """Privileged information of the current episode, only the ``kinds`` asked for (see ``provides``)."""
        ...

    def close(self) -> None:
        """Release the world's resources (simulator, sockets)."""
        ...


class EnvSpec(Protocol):
    """A picklable recipe for a world, sent to every worker process (or Ray task) that builds one: a frozen
    dataclass, whose fields ``run.json`` records under ``config.env``."""

    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]

    @property
    def name(self) -> str:
        """The world's ``--env`` name."""
        ...

    @property
    def provides(self) -> frozenset[str]:
        """The privileged inputs (:data:`~drivenav.types.PRIVILEGED_KINDS`) this world can give agents."""
        ...

    def build(self, sim: SimConfig) -> Env:
        """A fresh world with these sensor and body settings."""
        ...


TARGET_SEEN_PIXELS = 150  # goal-instance pixels in one frame for the target to count as seen


def shows_goal(observation: Observation, goal_ids: NDArray[np.int64]) -> bool:
    """Whether an observation's ground-truth instance ids show a goal instance clearly (``target_seen``)."""
    if observation.semantic is None:
        return False
    return count_pixels_of(observation.semantic, goal_ids) >= TARGET_SEEN_PIXELS
