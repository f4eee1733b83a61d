"""The pose's height on the robot side: the wire carries it as a 4th number (a planar pose keeps its 3 numbers and
its bytes, and old 3-number poses still read), ROS odometry gives it from ``position.z``, and a served building (the
embedded world of several storeys as a robot) reports the heights the world has, step for step."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.envs.base import Env
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.robot import RobotSpec
from drivenav.episode import Episode
from drivenav.eval.runner import RunSpec, build_agent, run_episode
from drivenav.robot.ros.convert import odometry_to_pose
from drivenav.robot.server import RobotSession, served
from drivenav.robot.sim import SimulatedRobot
from drivenav.settings import Settings, load_settings
from drivenav.types import Action, Pose
from drivenav.wire.protocol import REPLIES, Message, ProtocolError, decode, encode

SCENES, SEED = "storeys:2", 1  # storeys/home_01001: two storeys
STOREY = 2.4  # metres: the least floor-to-floor height


def sent_and_read(pose: Pose) -> tuple[list[float], Message]:
    """An observation's header ``pose`` as written, and the message read back."""
    frames = encode(Message("OBSERVATION", "r1", pose=pose, odom=pose))
    return json.loads(bytes(frames[0]))["pose"], decode([bytes(f) for f in frames], REPLIES)


def test_a_planar_pose_keeps_its_three_numbers() -> None:
    written, read = sent_and_read(Pose(1.0, -2.0, 0.5))
    assert written == [1.0, -2.0, 0.5]
    assert read.pose == Pose(1.0, -2.0, 0.5, 0.0) and read.odom == read.pose


def test_a_pose_with_a_height_travels_as_a_fourth_number() -> None:
    written, read = sent_and_read(Pose(1.0, -2.0, 0.5, 2.907915))
    assert written == [1.0, -2.0, 0.5, 2.907915]
    assert read.pose == Pose(1.0, -2.0, 0.5, 2.907915) and read.odom == read.pose


def test_old_three_number_poses_read_and_other_lengths_are_refused() -> None:
    header = {"protocol": "drivenav-robot", "version": 1, "type": "OBSERVATION", "id": "r1", "pose": [1, 2, 0.5]}
    assert decode([json.dumps(header).encode()], REPLIES).pose == Pose(1.0, 2.0, 0.5)
    for pose in ([1, 2, 0.5, "up"], [1, 2, 0.5, 3.0, 4.0], [1, 2]):
        with pytest.raises(ProtocolError, match="field 'pose'"):
            decode([json.dumps({**header, "pose": pose}).encode()], REPLIES)


def test_ros_odometry_gives_the_height() -> None:
    position = SimpleNamespace(x=1.5, y=-2.0, z=2.9)
    orientation = SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)
    pose = odometry_to_pose(
        SimpleNamespace(pose=SimpleNamespace(pose=SimpleNamespace(position=position, orientation=orientation)))
    )
    assert pose == Pose(1.5, -2.0, 0.0, 2.9)


@pytest.fixture(scope="module")
def settings() -> Settings:
    return load_settings("oracle", options={"sim.width": 96, "sim.height": 72})


@pytest.fixture(scope="module")
def climb() -> Episode:
    """An episode that starts on the ground floor and needs a floor change."""
    episodes = generate_episodes(SceneLibrary(SCENES, SEED), 2, SEED, storeys=Storeys(1.0))
    return next(e for e in episodes if e.info.get("cross_floor") and e.start_height == 0.0)


def heights(world: Env, episode: Episode, actions: tuple[int, ...]) -> list[tuple[float, float]]:
    """``Observation.pose.z`` and ``world_pose().z`` after the reset and each of ``actions``."""
    seen = [world.reset(episode).pose.z]
    poses = [world.world_pose().z]
    for action in actions:
        seen.append(world.step(Action(action)).pose.z)
        poses.append(world.world_pose().z)
    return list(zip(seen, poses, strict=True))


def test_a_served_building_reports_the_heights_of_the_world(settings: Settings, climb: Episode) -> None:
    """The oracle's climb, replayed through serve-sim and the brain's RobotEnv: every height is the world's own."""
    spec = EmbeddedSpec(SCENES, SEED)
    world = spec.build(settings.sim)
    record, trace = run_episode(world, build_agent(RunSpec(spec, settings)), climb, 0, settings.sim.max_steps)
    assert record.success == 1
    direct = heights(world, climb, trace.actions)
    assert direct[-1][0] >= STOREY  # upstairs
    robot = SimulatedRobot(spec.build(settings.sim), [climb])
    with served(RobotSession(robot.info(), robot, robot, robot)) as endpoint:
        brain = RobotSpec(endpoint, "", ("semantic",)).build(settings.sim)
        try:
            assert heights(brain, climb, trace.actions) == direct
        finally:
            brain.close()
