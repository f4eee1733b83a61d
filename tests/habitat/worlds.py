"""Shared set-up of the Habitat adapter's tests: embedded episodes exported to a Habitat data folder, and the
runs of one episode in both worlds."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from drivenav_sim import SCENES, SIM_NAME

from drivenav.agents import make_agent
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import BENCHMARKS
from drivenav.envs.habitat.env import HabitatEnv
from drivenav.envs.habitat.layouts import write_split
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.runner import run_episode
from drivenav.eval.trace import EpisodeTrace
from drivenav.settings import Settings, load_settings

SIM_OVERRIDE = f"habitat.simulator.type={SIM_NAME}"
SPLITS = {"hm3d-ovon": "val_seen", "hm3d-v1": "val"}  # one benchmark per layout


def export(episodes: list[Episode], data_dir: Path, benchmark: str) -> HabitatSpec:
    """Write ``episodes`` where ``benchmark``'s split lies under ``data_dir``; its spec on DriveNavSim-v0."""
    bench = BENCHMARKS[benchmark]
    split = SPLITS[benchmark]
    write_split(episodes, data_dir / bench.data_path.format(split=split), bench.layout)
    return HabitatSpec(benchmark, split, str(data_dir), (SIM_OVERRIDE,), semantic=True)


def settings_for(agent: str, benchmark: str, *overrides: str) -> Settings:
    return load_settings(agent, configs=[benchmark], overrides=overrides)


@dataclass
class BothWorlds:
    """One embedded world and one habitat.Env over DriveNavSim-v0 with the same settings."""

    spec: HabitatSpec
    settings: Settings

    def __post_init__(self) -> None:
        self.embedded = EmbeddedEnv(SceneLibrary(SCENES, 0).load, self.settings.sim)
        self.habitat = HabitatEnv(self.spec, self.settings.sim)

    def direct(self, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """The record and trace of one episode in the embedded world, with a fresh agent."""
        return run_episode(self.embedded, make_agent(self.settings), episode, 0, self.settings.sim.max_steps)

    def through(self, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """The record and trace of one episode through habitat.Env, with a fresh agent."""
        return run_episode(self.habitat, make_agent(self.settings), episode, 0, self.settings.sim.max_steps)

    def close(self) -> None:
        self.embedded.close()
        self.habitat.close()
