"""Shared set-up of the Habitat adapter's tests: embedded episodes exported to a Habitat data folder, the runs of
one episode in both worlds, and what two runs must share."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
from drivenav_sim import LIBRARY, SIM_NAME

from drivenav.agents import make_agent
from drivenav.envs.base import Env, EpisodeMeasures
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.habitat.benchmarks import BENCHMARKS
from drivenav.envs.habitat.env import HabitatEnv
from drivenav.envs.habitat.layouts import write_split
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.runner import run_episode
from drivenav.eval.trace import EpisodeTrace
from drivenav.settings import Settings, load_settings
from drivenav.types import Action, GroundTruth, Observation, Pose, SimConfig

SIM_OVERRIDE = f"habitat.simulator.type={SIM_NAME}"
SPLITS = {"hm3d-ovon": "val_seen", "hm3d-v1": "val", "mp3d": "val"}  # one benchmark per layout, and MP3D's
TOLERANCE = 1e-6  # metres (SPL: its value) between the two worlds' metrics


def export(episodes: list[Episode], data_dir: Path, benchmark: str) -> HabitatSpec:
    """Write ``episodes`` where ``benchmark``'s split lies under ``data_dir``; its spec on DriveNavSim-v0."""
    bench = BENCHMARKS[benchmark]
    write_split(episodes, split_file(data_dir, benchmark), bench.layout)
    return spec_of(data_dir, benchmark)


def split_file(data_dir: Path, benchmark: str) -> Path:
    """Where ``benchmark``'s split of these tests lies under ``data_dir``."""
    return data_dir / BENCHMARKS[benchmark].data_path.format(split=SPLITS[benchmark])


def spec_of(data_dir: Path, benchmark: str) -> HabitatSpec:
    """The spec of ``benchmark``'s split under ``data_dir`` on DriveNavSim-v0, with the semantic sensor."""
    return HabitatSpec(benchmark, SPLITS[benchmark], str(data_dir), (SIM_OVERRIDE,), semantic=True)


def settings_for(agent: str, benchmark: str, *overrides: str) -> Settings:
    return load_settings(agent, configs=[benchmark], overrides=overrides)


@dataclass
class BothWorlds:
    """One embedded world and one habitat.Env over DriveNavSim-v0 with the same settings."""

    spec: HabitatSpec
    settings: Settings

    def __post_init__(self) -> None:
        self.embedded = EmbeddedEnv(LIBRARY.load, self.settings.sim)
        self.habitat = HabitatEnv(self.spec, self.settings.sim)

    def direct(self, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """The record and trace of one episode in the embedded world, with a fresh agent."""
        return self.run(self.embedded, episode)

    def through(self, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """The record and trace of one episode through habitat.Env, with a fresh agent."""
        return self.run(self.habitat, episode)

    def run(self, world: Env, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """The record and trace of one episode in ``world`` (one of the two, or a wrapper), with a fresh agent."""
        return run_episode(world, make_agent(self.settings), episode, 0, self.settings.sim.max_steps)

    def close(self) -> None:
        self.embedded.close()
        self.habitat.close()


class NotedHeights:
    """A world that notes its heights after its reset and each step: the observation's (``Observation.pose.z``,
    above the start) and the world pose's (``world_pose().z``); all else is the world's own."""

    def __init__(self, world: Env) -> None:
        self.world = world
        self.heights: list[tuple[float, float]] = []

    @property
    def config(self) -> SimConfig:
        return self.world.config

    def reset(self, episode: Episode) -> Observation:
        self.heights = []
        return self._note(self.world.reset(episode))

    def step(self, action: Action) -> Observation:
        return self._note(self.world.step(action))

    def world_pose(self) -> Pose:
        return self.world.world_pose()

    def measures(self) -> EpisodeMeasures:
        return self.world.measures()

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        return self.world.ground_truth(kinds)

    def close(self) -> None:
        self.world.close()

    def _note(self, observation: Observation) -> Observation:
        self.heights.append((observation.pose.z, self.world.world_pose().z))
        return observation


def assert_same(
    direct: tuple[EpisodeRecord, EpisodeTrace], through: tuple[EpisodeRecord, EpisodeTrace], where: str
) -> None:
    """The same actions, and the same metrics (within :data:`TOLERANCE`), in both worlds."""
    (ours, our_trace), (theirs, their_trace) = direct, through
    assert theirs.error == "" and ours.error == "", (where, theirs.error, ours.error)
    assert their_trace.actions == our_trace.actions, where
    assert theirs.success == ours.success, where
    for key in ("spl", "distance_to_goal", "geodesic_distance", "path_length"):
        assert getattr(theirs, key) == pytest.approx(getattr(ours, key), abs=TOLERANCE), (where, key)
    assert (theirs.collisions, theirs.stop_reason) == (ours.collisions, ours.stop_reason), where
    assert (theirs.failure_cause, theirs.revisits) == (ours.failure_cause, ours.revisits), where
