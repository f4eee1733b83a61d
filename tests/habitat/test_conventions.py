"""Hand cases for habitat-lab's conventions as the adapter reads them: actions by name, GPS (forward, right),
the compass's sign, depth normalisation and a missing depth return, and the world frame of the agent state."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from habitat.core.registry import registry
from omegaconf import OmegaConf
from worlds import export, settings_for

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.env import HabitatEnv, check_gps_compass
from drivenav.envs.habitat.observations import depth_in_metres, pose_from_gps_compass
from drivenav.episode import Episode
from drivenav.types import Action, Pose, SimConfig

TURN = math.radians(30.0)


@pytest.fixture(scope="module")
def episode(tmp_path_factory: pytest.TempPathFactory) -> Episode:
    """A generated episode as the Habitat layouts hold it (coordinates to habitat-lab's 5 decimals)."""
    spec = export(generate_episodes(SceneLibrary("procedural", 0), 1, 11), tmp_path_factory.mktemp("held"), "hm3d-ovon")
    return spec.episodes()[0]


@pytest.fixture()
def env(episode: Episode, tmp_path: Path) -> Iterator[HabitatEnv]:
    world = HabitatEnv(export([episode], tmp_path / "data", "hm3d-ovon"), settings_for("oracle", "hm3d-ovon").sim)
    yield world
    world.close()


def _free_left_turns(episode: Episode) -> int:
    """How many left turns from the start heading give a forward step that does not collide (embedded world)."""
    world = EmbeddedEnv(SceneLibrary("procedural", 0).load)
    world.reset(episode)
    x, y = episode.start_xy
    for turns in range(1, 12):
        if not world.forward(x, y, episode.start_yaw + turns * TURN, 0.25)[2]:
            return turns
    raise AssertionError("no free heading at the start")


def test_turn_left_then_forward(env: HabitatEnv, episode: Episode) -> None:
    """k left turns and a 0.25 m step: GPS (forward, right) = 0.25 (cos, -sin) of k*30 degrees, the compass
    +k*30 degrees (counter-clockwise positive); drivenav's pose is (x forward, y left, yaw counter-clockwise)."""
    turns = _free_left_turns(episode)
    first = env.reset(episode)
    assert (first.pose.x, first.pose.y, first.pose.yaw) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    for _ in range(turns):
        turned = env.step(Action.TURN_LEFT)
    angle = math.remainder(turns * TURN, 2 * math.pi)
    assert turned.pose.yaw == pytest.approx(angle, abs=1e-9)
    raw = env.habitat_env.step("move_forward")
    assert not env.habitat_env.sim.previous_step_collided
    assert raw["gps"] == pytest.approx([0.25 * math.cos(angle), -0.25 * math.sin(angle)], abs=1e-5)
    assert float(raw["compass"][0]) == pytest.approx(angle, abs=1e-5)
    pose = pose_from_gps_compass(raw["gps"], raw["compass"])
    assert (pose.x, pose.y, pose.yaw) == pytest.approx(
        (0.25 * math.cos(angle), 0.25 * math.sin(angle), angle), abs=1e-5
    )


def test_steps_go_by_action_name_not_by_the_sorted_action_space(env: HabitatEnv, episode: Episode) -> None:
    env.reset(episode)
    assert list(env.habitat_env.task.actions) == ["stop", "move_forward", "turn_left", "turn_right"]
    assert sorted(env.habitat_env.action_space.spaces) == ["move_forward", "stop", "turn_left", "turn_right"]
    right = env.step(Action.TURN_RIGHT)
    assert right.pose.yaw == pytest.approx(-TURN, abs=1e-9)


def test_world_pose_is_the_scene_frame(env: HabitatEnv, episode: Episode) -> None:
    env.reset(episode)
    pose = env.world_pose()
    assert (pose.x, pose.y) == pytest.approx(episode.start_xy, abs=1e-9)
    assert math.remainder(pose.yaw - episode.start_yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_stop_ends_the_episode_through_step_none(env: HabitatEnv, episode: Episode) -> None:
    env.reset(episode)
    last = env.step(Action.STOP)
    assert env.habitat_env.episode_over
    assert (last.pose.x, last.pose.y, last.pose.yaw) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert env.measures().success == 0  # the start is not at a goal


def _depth_sensor(sim: SimConfig) -> object:
    config = OmegaConf.create(
        {
            "type": "HabitatSimDepthSensor",
            "uuid": "depth",
            "width": 4,
            "height": 1,
            "hfov": 79,
            "min_depth": sim.min_depth,
            "max_depth": sim.max_depth,
            "normalize_depth": True,
            "position": [0.0, 0.88, 0.0],
            "orientation": [0.0, 0.0, 0.0],
            "sensor_subtype": "PINHOLE",
            "noise_model": "None",
            "noise_model_kwargs": {},
        }
    )
    return registry.get_sensor(config.type)(config)


def test_depth_through_habitat_labs_sensor() -> None:
    """A missing return (raw 0) and anything nearer than min_depth read as min_depth, a clip value the mapper
    ignores; beyond max_depth reads max_depth; in-range metres come back to within float32 rounding."""
    sim = SimConfig()
    raw = np.array([[0.0, 0.3, 2.0, 7.5]], dtype=np.float32)
    normalised = _depth_sensor(sim).get_observation({"depth": raw})  # type: ignore[attr-defined]
    assert normalised.shape == (1, 4, 1)
    assert normalised[0, :, 0] == pytest.approx([0.0, 0.0, 1.5 / 4.5, 1.0])
    metres = depth_in_metres(normalised, sim)
    assert metres.shape == (1, 4)
    assert metres[0, 0] == sim.min_depth and metres[0, 1] == sim.min_depth and metres[0, 3] == sim.max_depth
    assert metres[0, 2] == pytest.approx(2.0, abs=1e-6)


def test_a_changed_gps_convention_stops_the_episode() -> None:
    check_gps_compass(Pose(1.0, 2.0, 0.5), Pose(1.0, 2.0, 0.5))
    with pytest.raises(ValueError, match="GPS/compass"):
        check_gps_compass(Pose(1.0, -2.0, 0.5), Pose(1.0, 2.0, 0.5))  # the right-handed flip forgotten
    with pytest.raises(ValueError, match="GPS/compass"):
        check_gps_compass(Pose(1.0, 2.0, -0.5), Pose(1.0, 2.0, 0.5))  # a clockwise compass
