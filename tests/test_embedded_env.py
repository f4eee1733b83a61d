"""EmbeddedEnv: reset/step semantics, episode-frame poses, caching and pickling."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.grid import GridSpec
from drivenav.types import Action, Pose, SimConfig


def hall_scene(scene_id: str) -> Scene:
    """A 6 m x 4 m walled hall with one chair (instance 11) near its east end."""
    structure = np.zeros((80, 120), np.uint8)
    structure[0, :] = structure[-1, :] = Material.WALL
    structure[:, 0] = structure[:, -1] = Material.WALL
    chair = ObjectInstance(11, "chair", (5.0, 1.0), (0.5, 0.5, 0.9))
    return Scene(scene_id, GridSpec(0.05, (0.0, 0.0), (80, 120)), structure, [chair])


class CountingLoader:
    """A picklable scene loader that counts its calls."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, scene_id: str) -> Scene:
        self.calls += 1
        return hall_scene(scene_id)


def episode(x: float, y: float, yaw: float, scene_id: str = "hall") -> Episode:
    return Episode(
        episode_id="e0",
        scene_id=scene_id,
        start_position=world_to_habitat(x, y),
        start_rotation=yaw_to_quaternion(yaw),
        object_category="chair",
        goals=(),
    )


def make_env() -> EmbeddedEnv:
    return EmbeddedEnv(CountingLoader(), SimConfig())


def test_reset_observation() -> None:
    env = make_env()
    obs = env.reset(episode(2.0, 2.0, 0.7))
    assert obs.step == 0 and not obs.collided
    assert (obs.pose.x, obs.pose.y, obs.pose.yaw) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert obs.rgb.shape == (480, 640, 3) and obs.depth.dtype == np.float32
    assert obs.semantic is not None and obs.semantic.dtype == np.int32
    assert env.start_pose.x == pytest.approx(2.0) and env.start_pose.yaw == pytest.approx(0.7)
    assert env.state == env.start_pose and env.steps == 0


def test_forward_four_times_is_one_metre_in_episode_frame() -> None:
    env = make_env()
    env.reset(episode(1.5, 2.0, 2.0))
    for _ in range(4):
        obs = env.step(Action.MOVE_FORWARD)
    assert (obs.pose.x, obs.pose.y, obs.pose.yaw) == pytest.approx((1.0, 0.0, 0.0), abs=1e-9)
    assert obs.step == 4 and env.steps == 4
    world = env.state
    assert world.x == pytest.approx(1.5 + math.cos(2.0)) and world.y == pytest.approx(2.0 + math.sin(2.0))


def test_turn_then_forward_pose() -> None:
    env = make_env()
    env.reset(episode(2.0, 2.0, -1.0))
    env.step(Action.MOVE_FORWARD)
    for _ in range(3):
        env.step(Action.TURN_LEFT)
    obs = env.step(Action.MOVE_FORWARD)
    assert (obs.pose.x, obs.pose.y, obs.pose.yaw) == pytest.approx((0.25, 0.25, math.pi / 2), abs=1e-9)
    obs = env.step(Action.TURN_RIGHT)
    assert obs.pose.yaw == pytest.approx(math.pi / 3)
    assert obs.step == 6


def test_full_turn_gives_identical_images() -> None:
    env = make_env()
    first = env.reset(episode(2.0, 2.0, 0.4))
    for _ in range(12):
        obs = env.step(Action.TURN_LEFT)
    assert env.state == env.start_pose
    assert np.array_equal(obs.rgb, first.rgb) and np.array_equal(obs.depth, first.depth)
    assert obs.semantic is not None and first.semantic is not None
    assert np.array_equal(obs.semantic, first.semantic)
    assert obs.pose.yaw == pytest.approx(0.0, abs=1e-12)


def test_stop_counts_but_does_not_move() -> None:
    env = make_env()
    env.reset(episode(2.0, 2.0, 0.0))
    obs = env.step(Action.STOP)
    assert obs.step == 1 and env.state == env.start_pose and not obs.collided


def test_forward_into_wall_collides() -> None:
    env = make_env()
    env.reset(episode(5.7, 3.0, 0.0))  # east wall's inner face at x = 5.95, radius 0.18
    obs = env.step(Action.MOVE_FORWARD)
    assert obs.collided
    nav = env.scene.navigable_grid(env.config.agent_radius, env.config.agent_height)
    row, col = env.scene.grid.world_to_cell((env.state.x, env.state.y))
    assert nav[row, col]
    assert 5.7 <= env.state.x <= 5.8  # clearance is measured between cell centres


def test_sees_the_chair_with_its_instance_id() -> None:
    env = make_env()
    obs = env.reset(episode(2.0, 1.0, 0.0))
    assert obs.semantic is not None
    assert set(np.unique(obs.semantic)) == {0, 11}
    assert obs.depth[300, 320] == pytest.approx(2.75, abs=1e-3)  # chair front face at x = 4.75


def test_non_navigable_start_raises() -> None:
    env = make_env()
    with pytest.raises(ValueError, match="not navigable"):
        env.reset(episode(0.1, 2.0, 0.0))  # within the agent radius of the west wall
    with pytest.raises(ValueError):
        env.reset(episode(5.0, 1.0, 0.0))  # inside the chair


def test_scene_cache_and_pickling() -> None:
    loader = CountingLoader()
    env = EmbeddedEnv(loader)
    env.reset(episode(2.0, 2.0, 0.0))
    env.reset(episode(3.0, 2.0, 0.0))
    assert loader.calls == 1
    env.step(Action.MOVE_FORWARD)
    blob = pickle.dumps(env)
    assert len(blob) < 10_000  # no scene, grid or renderer inside
    clone = pickle.loads(blob)
    assert clone.state == env.state and clone.steps == env.steps
    obs = clone.step(Action.MOVE_FORWARD)
    assert obs.pose.x == pytest.approx(0.5)


class CacheWatchingLoader(CountingLoader):
    """Records, at every load, how many scenes the environment still held (``env`` is set after construction)."""

    def __init__(self) -> None:
        super().__init__()
        self.env: EmbeddedEnv | None = None
        self.held_at_load: list[int] = []

    def __call__(self, scene_id: str) -> Scene:
        assert self.env is not None
        self.held_at_load.append(len(self.env._worlds))
        return super().__call__(scene_id)


def test_scene_cache_keeps_the_most_recent_scenes_and_evicts_before_loading() -> None:
    loader = CacheWatchingLoader()
    env = loader.env = EmbeddedEnv(loader, cache_size=2)
    for scene_id in ("a", "b", "a", "c", "a", "b"):  # c evicts b (a was used last); b evicts c
        env.reset(episode(2.0, 2.0, 0.0, scene_id))
    assert loader.calls == 4 and list(env._worlds) == ["a", "b"]
    assert loader.held_at_load == [0, 1, 1, 1]  # a full cache drops its oldest scene before the next one loads


def test_render_any_world_pose() -> None:
    env = make_env()
    env.reset(episode(2.0, 2.0, 0.0))
    rgb, depth, sem = env.render(Pose(3.95, 2.0, 0.0))
    assert rgb.shape == (480, 640, 3)
    assert depth[240, 320] == pytest.approx(2.0, abs=1e-3) and sem[240, 320] == 0


def test_step_before_reset_raises() -> None:
    with pytest.raises(RuntimeError):
        make_env().step(Action.STOP)


def test_rgb_is_rendered_only_when_read_and_equals_the_eager_frame() -> None:
    env = make_env()
    env.reset(episode(2.0, 2.0, 0.0))
    obs = env.step(Action.TURN_LEFT)
    env.step(Action.MOVE_FORWARD)  # the world moves on before the image is read
    assert "rgb" not in vars(obs)
    world_pose = Pose(2.0, 2.0, math.radians(30.0))
    rgb, depth, semantic = env.render(world_pose)
    np.testing.assert_array_equal(obs.depth, depth)
    np.testing.assert_array_equal(obs.semantic, semantic)
    np.testing.assert_array_equal(obs.rgb, rgb)
    assert obs.rgb is obs.rgb  # rendered once, then kept
