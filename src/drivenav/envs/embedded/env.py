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
from drivenav.envs.embedded.building import Building, storeys_of
from drivenav.envs.embedded.measures import EmbeddedMeasures
from drivenav.envs.embedded.render import Images, Renderer
from drivenav.envs.embedded.scene import Scene
from drivenav.envs.embedded.terrain import DistanceField, Terrain, terrain_of
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.episode import Episode
from drivenav.grid import wrap_angle
from drivenav.types import GEODESIC, SEMANTIC, Action, GroundTruth, Observation, Pose, SimConfig

_DEFAULT_CONFIG = SimConfig()
_GEODESIC_CACHE = 4  # target sets whose distance fields are kept


@dataclass(frozen=True)
class _World:
    """A loaded scene or building with what the env derives from it."""

    scene: Scene | Building
    terrain: Terrain  # where the agent can stand and go; its reachable part is where episodes start
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
    field: DistanceField
    start_pose: Pose
    step: float
    goal_heights: tuple[float, ...]

    def distance(self, pose: Pose) -> float:
        return float(self.field.at(pose.x, pose.y, pose.z))

    def forward(self, pose: Pose) -> tuple[Pose, bool]:
        (x, y, z), collided = self.world.terrain.forward(pose.x, pose.y, pose.z, pose.yaw, self.step)
        return Pose(x, y, pose.yaw, z), collided


class EmbeddedEnv:
    """ObjectNav environment over embedded scenes and buildings (Habitat action space and sensor defaults).

    ``scene_loader`` maps an episode's ``scene_id`` to a :class:`Scene` or a :class:`Building`; up to ``cache_size``
    loaded scenes are kept. The agent stands on the floor under it: a start is placed on the floor nearest its height
    (an episode's ``start_position[1]``), and every pose carries that floor's height. Headings are kept as a whole
    number of turns from the start heading, so turning a full circle gives back exactly the start yaw.
    """

    def __init__(
        self, scene_loader: Callable[[str], Scene | Building], config: SimConfig = _DEFAULT_CONFIG, cache_size: int = 2
    ) -> None:
        self._loader = scene_loader
        self._config = config
        self._cache_size = max(1, cache_size)
        self._worlds: OrderedDict[str, _World] = OrderedDict()
        self._scene_id: str | None = None
        self._start = Pose(0.0, 0.0, 0.0)
        self._goal_heights: tuple[float, ...] = ()
        self._xyz = (0.0, 0.0, 0.0)
        self._turns = 0
        self._steps = 0
        self._measures = EmbeddedMeasures(config)
        self._fields: OrderedDict[tuple[str | None, tuple[tuple[float, ...], ...]], DistanceField] = OrderedDict()

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
    def scene(self) -> Scene | Building:
        """The current episode's scene or building."""
        return self._world().scene

    @property
    def start_pose(self) -> Pose:
        """The episode's start pose in the world frame."""
        return self._start

    @property
    def state(self) -> Pose:
        """The agent's current pose in the world frame (its height that of the floor under it)."""
        x, y, z = self._xyz
        return Pose(x, y, self._yaw(), z)

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
        z = world.terrain.place(x, y, episode.start_height)
        if z is None:
            where = f"{(x, y)} at height {episode.start_height:g}" if episode.start_height else f"{(x, y)}"
            raise ValueError(f"episode {episode.episode_id}: start {where} is not navigable in {episode.scene_id}")
        self._start = Pose(x, y, wrap_angle(episode.start_yaw), z)
        self._xyz = (x, y, z)
        self._turns = 0
        self._steps = 0
        goal_ids = [goal.object_id for goal in episode.goals]
        view_points = episode.view_points_xyz()
        self._goal_heights = tuple(sorted({height for *_, height in view_points}))
        self._measures.reset(world.terrain.field(view_points), self._start, goal_ids)
        observation = self._observe(collided=False)
        self._measures.update(None, self.state, observation)
        return observation

    def step(self, action: Action) -> Observation:
        """Apply one action (Habitat semantics: 0.25 m forward, 30 degree turns, STOP does not move)."""
        world = self._world()
        collided = False
        if action == Action.MOVE_FORWARD:
            x, y, z = self._xyz
            self._xyz, collided = world.terrain.forward(x, y, z, self._yaw(), self._config.forward_step)
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
        objects = [obj for storey in storeys_of(world.scene) for obj in storey.plan.objects]
        labels = {obj.instance_id: obj.category for obj in objects} if semantic else None
        geodesic = None
        if GEODESIC in kinds:
            field, step = self._measures.goal_field, self._config.forward_step
            geodesic = _Geodesic(world, field, self._start, step, self._goal_heights)
        return GroundTruth(labels, VOCABULARY if semantic else None, geodesic)

    def close(self) -> None:
        """Drop the loaded scenes."""
        self._worlds.clear()
        self._fields.clear()

    def geodesic_distance(self, x: float, y: float, targets: Sequence[tuple[float, ...]], z: float = 0.0) -> float:
        """Geodesic distance (metres, inf if unreachable) from a world point (at height ``z``) to the nearest of
        ``targets`` (``(x, y)`` on a one-floor scene's floor, or ``(x, y, height)``) over the current scene's
        reachable area: the measure of :class:`EmbeddedMeasures`, as a simulator's path finder answers it (one
        distance solve per target set, the last few kept)."""
        world = self._world()
        key = (self._scene_id, tuple(targets))
        field = self._fields.get(key)
        if field is None:
            field = world.terrain.field([(t[0], t[1], t[2] if len(t) > 2 else 0.0) for t in targets])
            self._fields[key] = field
            while len(self._fields) > _GEODESIC_CACHE:
                self._fields.popitem(last=False)
        return float(field.at(x, y, z))

    def forward(self, x: float, y: float, yaw: float, step: float, z: float = 0.0) -> tuple[float, float, bool]:
        """Where a straight move of ``step`` metres from a world point (at height ``z``) along ``yaw`` ends in the
        current scene (sliding along walls), and whether it collided: the world's motion model."""
        (nx, ny, _), collided = self._world().terrain.forward(x, y, z, yaw, step)
        return nx, ny, collided

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
            world = _World(scene, terrain_of(scene, self._config), Renderer(scene, self._config))
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
