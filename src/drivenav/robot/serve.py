"""``drivenav robot serve`` and ``serve-sim``: build a robot's parts and serve them until Ctrl-C."""

from __future__ import annotations

import threading
from pathlib import Path

from drivenav.robot.lidar import LidarConfig, LidarOccupancy
from drivenav.robot.parts import MotionExecutor, SensorSource
from drivenav.robot.server import EpisodeWorld, RobotServer, RobotSession, ServerConfig
from drivenav.types import SimConfig
from drivenav.wire.protocol import RobotInfo
from drivenav.wire.security import check_bind


def run_server(session: RobotSession, bind: str, keys: Path | None) -> None:
    """Serve ``session`` at ``bind`` until Ctrl-C (or SIGTERM: the command line says it stopped serving); the
    robot is stopped on the way out."""
    server = RobotServer(session, bind, keys)
    print(f"serving on {server.endpoint}{' with CURVE' if keys else ''} (Ctrl-C stops)", flush=True)
    try:
        server.serve(threading.Event())
    finally:
        server.close()
        session.source.close()


def lidar_for(sim: SimConfig, enabled: bool) -> LidarOccupancy | None:
    """The FOV-limited LiDAR occupancy (Sec. V-E) matching the camera's field of view, when ``enabled``."""
    if not enabled:
        return None
    return LidarOccupancy(
        LidarConfig(hfov_deg=sim.hfov_deg, max_height=sim.agent_height, resolution=sim.grid_resolution)
    )


def serve_simulation(
    scenes: str, seed: int, episodes_file: Path, bind: str, keys: Path | None, lidar: bool, sim: SimConfig
) -> None:
    """The embedded world over ``scenes`` served as a robot that knows the episodes of ``episodes_file``."""
    from drivenav.envs.embedded.env import EmbeddedSpec
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import load_episodes, validate_for_scenes
    from drivenav.robot.sim import SimulatedLidar, SimulatedRobot

    check_bind(bind, keys)
    episodes = load_episodes(episodes_file)
    validate_for_scenes(episodes, SceneLibrary(scenes, seed), episodes_file, sim)
    robot = SimulatedRobot(EmbeddedSpec(scenes, seed).build(sim), episodes, SimulatedLidar() if lidar else None)
    session = RobotSession(robot.info(), robot, robot, robot, lidar_for(sim, lidar))
    run_server(session, bind, keys)


def serve_robot(
    bind: str,
    keys: Path | None,
    source: SensorSource,
    motion: MotionExecutor,
    sim: SimConfig,
    lidar: bool,
    jpeg: bool,
    episodes: EpisodeWorld | None = None,
) -> None:
    """A real robot's parts served at ``bind``: it says it has the sensor and body of ``sim``."""
    check_bind(bind, keys)
    info = RobotInfo.from_sim(sim, lidar=lidar, rgb_encoding="jpeg" if jpeg else "raw")
    config = ServerConfig(rgb_encoding=info.rgb_encoding)
    session = RobotSession(info, source, motion, episodes, lidar_for(sim, lidar), config)
    run_server(session, bind, keys)
