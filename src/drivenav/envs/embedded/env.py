"""The embedded simulator: an :class:`~drivenav.envs.base.Env` over 2.5-D scenes, rendered by numba.

It provides what the paper's problem formulation (Sec. III) gives the agent -- an egocentric RGB-D
observation and a pose relative to the start ``p_0`` at every step -- with the Habitat set-up of the
experiments (Sec. V-A: 79 degree RGB-D camera, 0.25 m steps, 30 degree turns), plus ground-truth instance ids.

The env moves the agent, renders, and keeps the Habitat measures
(:class:`~drivenav.envs.embedded.measures.EmbeddedMeasures`); step limits belong to the evaluator. It gives the
ground truth it has (instance labels, the goal's geodesic field and its own motion model) to the agents that ask.
It is cheap to construct and pickles without its scene cache (scenes are reloaded through ``scene_loader`` on
demand); :class:`EmbeddedSpec` builds one per worker.
"""

from __future__ import annotations

import functools
import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.base import EpisodeMeasures, episode_pose
from drivenav.envs.embedded.geodesic import GeodesicField, largest_component
from drivenav.envs.embedded.measures import EmbeddedMeasures
from drivenav.envs.embedded.motion import forward_step, is_navigable
from drivenav.envs.embedded.render import Images, Renderer
from drivenav.envs.embedded.scene import Scene
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.episode import Episode
from drivenav.grid import wrap_angle
from drivenav.types import GEODESIC, SEMANTIC, Action, GroundTruth, Observation, Pose, SimConfig

_DEFAULT_CONFIG = SimConfig()
_GEODESIC_CACHE = 4  # target sets whose distance fields are kept


@dataclass(frozen=True)
class _World:
    """A loaded scene with what the env derives from it."""

    scene: Scene
    navigable: NDArray[np.bool_]
    reachable: NDArray[np.bool_]  # the largest navigable component: where episodes start and goals are measured
    renderer: Renderer


@dataclass(frozen=True)
class EmbeddedSpec:
    """Builds :class:`EmbeddedEnv` over a ``--scenes`` SPEC in each worker (picklable)."""

    scenes: str = "procedural"
    seed: int = 0
    name: ClassVar[str] = "embedded"
    provides: ClassVar[frozenset[str]] = frozenset({SEMANTIC, GEODESIC})

    def build(self, sim: SimConfig) -> EmbeddedEnv:
        from drivenav.envs.embedded.library import SceneLibrary

        return EmbeddedEnv(SceneLibrary(self.scenes, self.seed).load, sim)


@dataclass(frozen=True)
class _Geodesic:
    """The embedded world's :class:`~drivenav.types.GeodesicOracle` for one episode."""

    world: _World
    field: GeodesicField
    start_pose: Pose
    step: float

    def distance(self, x: float, y: float) -> float:
        return float(self.field.at(x, y))

    def forward(self, x: float, y: float, yaw: float) -> tuple[float, float, bool]:
        return forward_step(self.world.navigable, self.world.scene.grid, x, y, yaw, self.step)


class EmbeddedEnv:
    """ObjectNav environment over embedded scenes (Habitat action space and sensor defaults).

    ``scene_loader`` maps an episode's ``scene_id`` to a :class:`Scene`; up to ``cache_size`` loaded scenes
    are kept. Headings are kept as a whole number of turns from the start heading, so turning a full circle
    gives back exactly the start yaw.
    """

    def __init__(
        self, scene_loader: Callable[[str], Scene], config: SimConfig = _DEFAULT_CONFIG, cache_size: int = 2
    ) -> None:
        self._loader = scene_loader
        self._config = config
        self._cache_size = max(1, cache_size)
        self._worlds: OrderedDict[str, _World] = OrderedDict()
        self._scene_id: str | None = None
        self._start = Pose(0.0, 0.0, 0.0)
        self._xy = (0.0, 0.0)
        self._turns = 0
        self._steps = 0
        self._measures = EmbeddedMeasures(config)
        self._fields: OrderedDict[tuple[str | None, tuple[tuple[float, float], ...]], GeodesicField] = OrderedDict()

    # -- pickling: drop the scene cache ---------------------------------------------------------------
    def __getstate__(self) -> dict[str, object]:
        state = dict(self.__dict__)
        state["_worlds"] = OrderedDict()
        state["_fields"] = OrderedDict()
        state["_measures"] = EmbeddedMeasures(self._config)
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)

    # -- read-only state ------------------------------------------------------------------------------
    @property
    def config(self) -> SimConfig:
        return self._config

    @property
    def scene(self) -> Scene:
        """The current episode's scene."""
        return self._world().scene

    @property
    def start_pose(self) -> Pose:
        """The episode's start pose in the world frame."""
        return self._start

    @property
    def state(self) -> Pose:
        """The agent's current pose in the world frame."""
        return Pose(self._xy[0], self._xy[1], self._yaw())

    @property
    def steps(self) -> int:
        """Actions taken since the last reset (turns and STOP included)."""
        return self._steps

    # -- Env protocol ---------------------------------------------------------------------------------
    def reset(self, episode: Episode) -> Observation:
        """Load the episode's scene and place the agent at its start (ValueError if not navigable)."""
        self._measures = EmbeddedMeasures(self._config)  # the last goal field goes before a scene loads
        self._scene_id = episode.scene_id
        world = self._world()
        x, y = episode.start_xy
        if not is_navigable(world.navigable, world.scene.grid, x, y):
            raise ValueError(f"episode {episode.episode_id}: start {(x, y)} is not navigable in {episode.scene_id}")
        self._start = Pose(x, y, wrap_angle(episode.start_yaw))
        self._xy = (x, y)
        self._turns = 0
        self._steps = 0
        self._measures.reset(episode, world.reachable, world.scene.grid, self._start)
        observation = self._observe(collided=False)
        self._measures.update(None, self.state, observation)
        return observation

    def step(self, action: Action) -> Observation:
        """Apply one action (Habitat semantics: 0.25 m forward, 30 degree turns, STOP does not move)."""
        world = self._world()
        collided = False
        if action == Action.MOVE_FORWARD:
            x, y, collided = forward_step(
                world.navigable,
                world.scene.grid,
                self._xy[0],
                self._xy[1],
                self._yaw(),
                self._config.forward_step,
            )
            self._xy = (x, y)
        elif action == Action.TURN_LEFT:
            self._turns = self._wrap_turns(self._turns + 1)
        elif action == Action.TURN_RIGHT:
            self._turns = self._wrap_turns(self._turns - 1)
        self._steps += 1
        observation = self._observe(collided)
        self._measures.update(action, self.state, observation)
        return observation

    def world_pose(self) -> Pose:
        return self.state

    def measures(self) -> EpisodeMeasures:
        return self._measures.result()

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        """Instance labels and the vocabulary (``semantic``); the goal field and motion model (``geodesic``)."""
        world = self._world()
        semantic = SEMANTIC in kinds
        labels = {obj.instance_id: obj.category for obj in world.scene.objects} if semantic else None
        geodesic = None
        if GEODESIC in kinds:
            geodesic = _Geodesic(world, self._measures.goal_field, self._start, self._config.forward_step)
        return GroundTruth(labels, VOCABULARY if semantic else None, geodesic)

    def close(self) -> None:
        """Drop the loaded scenes."""
        self._worlds.clear()
        self._fields.clear()

    def geodesic_distance(self, x: float, y: float, targets: Sequence[tuple[float, float]]) -> float:
        """Geodesic distance (metres, inf if unreachable) from a world point to the nearest of ``targets`` over the
        current scene's reachable cells: the measure of :class:`EmbeddedMeasures`, as a simulator's path finder
        answers it (one Fast-Marching solve per target set, the last few kept)."""
        world = self._world()
        key = (self._scene_id, tuple(targets))
        field = self._fields.get(key)
        if field is None:
            field = GeodesicField(world.reachable, world.scene.grid, list(targets))
            self._fields[key] = field
            while len(self._fields) > _GEODESIC_CACHE:
                self._fields.popitem(last=False)
        return float(field.at(x, y))

    def forward(self, x: float, y: float, yaw: float, step: float) -> tuple[float, float, bool]:
        """Where a straight move of ``step`` metres from a world point along ``yaw`` ends in the current scene
        (sliding along walls), and whether it collided: the world's motion model."""
        world = self._world()
        return forward_step(world.navigable, world.scene.grid, x, y, yaw, step)

    def render(self, pose_world: Pose) -> Images:
        """RGB, depth and semantic images from a world-frame pose of the current scene."""
        return self._world().renderer.render(pose_world)

    # -- internals --------------------------------------------------------------------------------------
    def _world(self) -> _World:
        if self._scene_id is None:
            raise RuntimeError("EmbeddedEnv: call reset() before using the scene")
        world = self._worlds.get(self._scene_id)
        if world is None:
            while len(self._worlds) >= self._cache_size:  # evicted before loading: a lower memory peak
                self._worlds.popitem(last=False)
            scene = self._loader(self._scene_id)
            cfg = self._config
            navigable = scene.navigable_grid(cfg.agent_radius, cfg.agent_height)
            world = _World(scene, navigable, largest_component(navigable), Renderer(scene, cfg))
            self._worlds[self._scene_id] = world
        self._worlds.move_to_end(self._scene_id)
        return world

    def _wrap_turns(self, turns: int) -> int:
        """Reduce a turn count modulo a full circle when the turn angle divides 360 degrees."""
        per_circle = 360.0 / self._config.turn_angle_deg
        if abs(per_circle - round(per_circle)) < 1e-9:
            return turns % round(per_circle)
        return turns

    def _yaw(self) -> float:
        return wrap_angle(self._start.yaw + self._turns * math.radians(self._config.turn_angle_deg))

    def _observe(self, collided: bool) -> Observation:
        """The observation at the current state; its RGB image is rendered only if someone reads it."""
        state = self.state
        renderer = self._world().renderer
        depth, semantic = renderer.render_geometry(state)
        return Observation.deferred(
            functools.partial(_rgb_image, renderer, state),
            depth=depth,
            semantic=semantic,
            pose=episode_pose(self._start, state),
            intrinsics=self._config.intrinsics,
            step=self._steps,
            collided=collided,
        )


def _rgb_image(renderer: Renderer, pose: Pose) -> NDArray[np.uint8]:
    """The RGB image from ``pose`` (a deferred observation's, rendered when read)."""
    return renderer.render(pose)[0]
