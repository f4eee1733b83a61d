"""The embedded world seen through a noisy depth camera: its env and its spec (what ``run.json`` records and every
worker builds the env from). Imported when a run uses the world (:mod:`.world` registers it)."""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from drivenav.envs.embedded.env import EmbeddedEnv, EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode
from drivenav.types import Action, Observation, SimConfig


class NoisyDepthEnv(EmbeddedEnv):
    """The embedded world whose depth camera adds Gaussian noise (seeded per episode)."""

    def __init__(self, spec: NoisyDepthSpec, sim: SimConfig) -> None:
        super().__init__(SceneLibrary(spec.scenes, spec.seed).load, sim)
        self._sigma = spec.depth_noise
        self._rng = np.random.default_rng(0)

    def _noisy(self, observation: Observation) -> Observation:
        noise = self._rng.normal(0.0, self._sigma, observation.depth.shape)
        depth = np.clip(observation.depth + noise, self.config.min_depth, self.config.max_depth)
        return replace(observation, depth=depth.astype(np.float32))

    def reset(self, episode: Episode) -> Observation:
        self._rng = np.random.default_rng(zlib.crc32(episode.episode_id.encode()))
        return self._noisy(super().reset(episode))

    def step(self, action: Action) -> Observation:
        return self._noisy(super().step(action))


@dataclass(frozen=True)
class NoisyDepthSpec(EmbeddedSpec):
    """The embedded spec and the depth noise."""

    depth_noise: float = 0.05  # metres, the standard deviation
    name: ClassVar[str] = "embedded-noisy"

    def build(self, sim: SimConfig) -> NoisyDepthEnv:
        return NoisyDepthEnv(self, sim)
