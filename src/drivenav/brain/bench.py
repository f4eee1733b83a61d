"""``drivenav bench robot``: the protocol's round trip of one 640x480 RGB-D observation on loopback, plain and
with CURVE (what a step costs on the wire before any motion)."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from drivenav.brain.live import live_episode
from drivenav.envs.robot import RobotEnv, RobotSpec
from drivenav.episode import Episode
from drivenav.robot.parts import HeldStill, SensorFrame
from drivenav.robot.server import RobotSession, served
from drivenav.types import Action, Pose, SimConfig
from drivenav.wire.protocol import RobotInfo
from drivenav.wire.security import write_keys


class StillCamera:
    """A sensor source that returns one fixed frame (a textured image, a ramp of depths)."""

    def __init__(self, sim: SimConfig) -> None:
        rng = np.random.default_rng(0)
        self.frame = SensorFrame(
            rgb=rng.integers(0, 256, (sim.height, sim.width, 3), dtype=np.uint8),
            depth=np.linspace(sim.min_depth, sim.max_depth, sim.height * sim.width, dtype=np.float32).reshape(
                sim.height, sim.width
            ),
            pose=Pose(0.0, 0.0, 0.0),
            intrinsics=sim.intrinsics,
            stamp=0.0,
        )

    def read(self) -> SensorFrame:
        return self.frame

    def close(self) -> None:
        """Nothing to release."""


def _round_trips(env: RobotEnv, episode: Episode, repeats: int) -> list[float]:
    env.reset(episode)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        env.step(Action.TURN_LEFT)
        times.append((time.perf_counter() - start) * 1e3)
    return times


def bench_robot(repeats: int = 200) -> dict[str, object]:
    """Median and 95th-percentile milliseconds of a STEP's round trip (request, 640x480 RGB + uint16 depth back,
    decoded into an observation), plain and with CURVE."""
    sim = SimConfig()
    result: dict[str, object] = {"frame": f"{sim.width}x{sim.height} rgb8 + depth16", "repeats": repeats}
    with tempfile.TemporaryDirectory() as folder:
        keys = Path(folder) / "keys"
        write_keys(keys)
        for label, server_keys in (("plain", None), ("curve", keys)):
            session = RobotSession(RobotInfo.from_sim(sim), StillCamera(sim), HeldStill())
            with served(session, server_keys) as endpoint:
                env = RobotSpec(endpoint, str(server_keys or "")).build(sim)
                try:
                    times = _round_trips(env, live_episode("bench"), repeats)
                finally:
                    env.close()
            result[f"{label}_median_ms"] = round(statistics.median(times), 3)
            result[f"{label}_p95_ms"] = round(float(np.percentile(times, 95)), 3)
    return result
