"""drivenav's embedded world as a habitat-lab simulator (``DriveNavSim-v0``), for the adapter's tests only.

It implements what habitat-lab's ``Env``, ObjectNav task, sensors and measures call on this path:
``sensor_suite`` (sensors built as habitat-lab builds them, ``registry.get_sensor(cfg.type)(cfg)``, so habitat-lab's
own RGB and depth sensor classes clip and normalise), ``reconfigure``, ``reset`` (the agent's start state from the
config, as the task writes it), ``step`` (also ``step(None)`` after STOP), ``step_physics``, ``get_agent_state``
(position array, ``quaternion.quaternion`` rotation), ``geodesic_distance``, ``previous_step_collided``, ``seed``,
``close``, and a ``pathfinder`` with ``try_step`` / ``try_step_no_sliding`` for the oracle's motion model. Raw depth
is metres, as habitat-sim's. Scenes are the embedded library's (``SCENES``: procedural houses and homes of several
storeys), found by the scene path's part after ``scene_datasets/`` (an HM3D-form path by its house's name:
:func:`embedded_scene_id`). Worker processes import it through ``--habitat-plugin drivenav_sim``.

Floors are habitat-sim's: a position's ``y`` is its height. The agent starts on the floor nearest the start state's
height (as the task writes the episode's start), ``get_agent_state`` reports the height of the floor or stairs under
it, ``geodesic_distance`` runs between 3-D points through the stairs, and the path finder's steps climb and descend
them (the embedded world's motion model, heights included).
"""

from __future__ import annotations

import standins

standins.install()  # also when a worker process imports this module as a --habitat-plugin

import math
import re
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
import quaternion
from gym import spaces
from habitat.core.registry import registry
from habitat.core.simulator import AgentState, SensorSuite, Simulator
from habitat.sims.habitat_simulator.actions import HabitatSimActions

from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import Scene
from drivenav.envs.embedded.terrain import Terrain, terrain_of
from drivenav.envs.habitat.benchmarks import SCENES_DIR
from drivenav.episode import Episode, habitat_to_world, world_to_habitat, yaw_to_quaternion
from drivenav.types import Action, Observation, SimConfig

SIM_NAME = "DriveNavSim-v0"
SCENES = "procedural,storeys"
LIBRARY = SceneLibrary(SCENES, 0)
SCENE_FOLDER = f"{SCENES_DIR}/"
HM3D_FORM = re.compile(r"hm3d/[^/]+/\d{5}-([^/]+)/\1\.basis\.glb")


def sim_config(config: Any) -> SimConfig:
    """drivenav's sensor and body settings read from habitat-lab's simulator config."""
    agent = config.agents[config.agents_order[config.default_agent_id]]
    depth = agent.sim_sensors.depth_sensor
    return SimConfig(
        width=int(depth.width),
        height=int(depth.height),
        hfov_deg=float(depth.hfov),
        camera_height=float(depth.position[1]),
        min_depth=float(depth.min_depth),
        max_depth=float(depth.max_depth),
        agent_radius=float(agent.radius),
        agent_height=float(agent.height),
        forward_step=float(config.forward_step_size),
        turn_angle_deg=float(config.turn_angle),
    )


def embedded_scene_id(scene: str) -> str:
    """The embedded scene of a scene path: its part after ``scene_datasets/``; a path in HM3D's form
    (``hm3d/<split>/<NNNNN>-<name>/<name>.basis.glb``, as released episode files name scenes) names the library's
    scene ``<name>`` (``house_SSSSS`` a procedural house, ``home_SSSSS`` a home of several storeys), so fixtures
    written like the released files run here."""
    scene = scene.split(SCENE_FOLDER, 1)[1] if SCENE_FOLDER in scene else scene
    match = HM3D_FORM.fullmatch(scene)
    if match is None:
        return scene
    named = [f"{part}/{match.group(1)}" for part in SCENES.split(",")]
    return next((scene_id for scene_id in named if scene_id in LIBRARY), named[0])


@dataclass(frozen=True)
class _Category:
    label: str

    def name(self) -> str:
        return self.label


@dataclass(frozen=True)
class _SemanticObject:
    semantic_id: int
    category: _Category


class _PathFinder:
    """habitat-sim's ``PathFinder.try_step`` family over the embedded motion model (which slides along walls and
    follows the floor and the stairs under it): the point reached from ``start`` toward ``end``, with its height.

    The model is the current scene's terrain, built here once per scene (``EmbeddedEnv.forward`` gives the point
    reached without its height)."""

    def __init__(self, sim: DriveNavSim) -> None:
        self._sim = sim
        self._terrain: tuple[Scene | Building, Terrain] | None = None

    def try_step(self, start: Any, end: Any) -> np.ndarray:
        (x0, y0), (x1, y1) = habitat_to_world(list(start)), habitat_to_world(list(end))
        yaw, step = math.atan2(y1 - y0, x1 - x0), math.hypot(x1 - x0, y1 - y0)
        (x, y, z), _ = self._current_terrain().forward(x0, y0, float(start[1]), yaw, step)
        return np.array(world_to_habitat(x, y, z))

    try_step_no_sliding = try_step

    def _current_terrain(self) -> Terrain:
        scene = self._sim.world.scene
        if self._terrain is None or self._terrain[0] is not scene:
            self._terrain = (scene, terrain_of(scene, self._sim.world.config))
        return self._terrain[1]


@registry.register_simulator(name=SIM_NAME)
class DriveNavSim(Simulator):  # type: ignore[misc]
    def __init__(self, config: Any) -> None:
        self.habitat_config = config
        sensors = [
            registry.get_sensor(cfg.type)(cfg) for agent in config.agents.values() for cfg in agent.sim_sensors.values()
        ]
        self._sensor_suite = SensorSuite(sensors)
        self.world = EmbeddedEnv(LIBRARY.load, sim_config(config))
        self.pathfinder = _PathFinder(self)
        self._collided = False
        self._last: Observation | None = None

    @property
    def sensor_suite(self) -> SensorSuite:
        return self._sensor_suite

    @property
    def action_space(self) -> spaces.Discrete:
        return spaces.Discrete(4)

    @property
    def previous_step_collided(self) -> bool:
        return self._collided

    def reconfigure(self, config: Any, ep_info: Any = None) -> None:
        self.habitat_config = config

    def reset(self) -> Any:
        """The agent at the start state the task wrote (the episode's start position, its height included)."""
        config = self.habitat_config
        agent = config.agents[config.agents_order[config.default_agent_id]]
        start = Episode(
            "sim", embedded_scene_id(config.scene), tuple(agent.start_position), tuple(agent.start_rotation), "", ()
        )
        self._collided = False
        self._last = self.world.reset(start)
        return self._sensor_observations()

    def step(self, action: Any) -> Any:
        if action is not None:
            self._last = self.world.step(_ACTIONS[int(action)])
            self._collided = self._last.collided
        return self._sensor_observations()

    def step_physics(self, dt: float) -> None:
        return None

    def get_agent_state(self, agent_id: int = 0) -> AgentState:
        pose = self.world.state
        x, y, z, w = yaw_to_quaternion(pose.yaw)
        return AgentState(np.array(world_to_habitat(pose.x, pose.y, pose.z)), quaternion.quaternion(w, x, y, z))

    def geodesic_distance(self, position_a: Any, position_b: Any, episode: Any = None) -> float:
        """Metres from ``position_a`` to the nearest of ``position_b`` (one position or several), heights included."""
        targets = position_b if np.ndim(position_b) == 2 else [position_b]
        x, y, z = _world_point(position_a)
        return self.world.geodesic_distance(x, y, [_world_point(p) for p in targets], z)

    def semantic_annotations(self) -> Any:
        """habitat-sim's semantic scene, as far as the adapter reads it: objects with ``semantic_id`` and
        ``category.name()``; a building's objects on every storey."""
        scene = self.world.scene
        placed = [obj for _, obj in scene.objects()] if isinstance(scene, Building) else scene.objects
        objects = [_SemanticObject(obj.instance_id, _Category(obj.category)) for obj in placed]
        return SimpleNamespace(objects=objects)

    def seed(self, seed: int) -> None:
        return None

    def close(self) -> None:
        self.world.close()

    def _sensor_observations(self) -> Any:
        assert self._last is not None
        raw = {"rgb": self._last.rgb, "depth": self._last.depth, "semantic": self._last.semantic}
        return self._sensor_suite.get_observations(raw)


def _world_point(position: Any) -> tuple[float, float, float]:
    """A Habitat position as a world point with its height."""
    x, y = habitat_to_world(list(position))
    return x, y, float(position[1])


_ACTIONS = {
    HabitatSimActions.stop: Action.STOP,
    HabitatSimActions.move_forward: Action.MOVE_FORWARD,
    HabitatSimActions.turn_left: Action.TURN_LEFT,
    HabitatSimActions.turn_right: Action.TURN_RIGHT,
}
