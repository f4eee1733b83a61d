"""The embedded simulator as a run sees it (``--env embedded``, the default): scenes from ``--scenes``, episodes
generated with the run seed or read from a file and checked against the scenes."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from drivenav.eval.options import episode_count, is_count
from drivenav.worlds.entry import SceneLoader, WorldEntry

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec
    from drivenav.episode import Episode
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings


def _spec_class() -> type[EnvSpec]:
    from drivenav.envs.embedded.env import EmbeddedSpec

    return EmbeddedSpec


def _build(args: argparse.Namespace, settings: Settings) -> EnvSpec:
    from drivenav.envs.embedded.env import EmbeddedSpec

    return EmbeddedSpec(args.scenes, settings.run.seed)


def load_or_generate(args: argparse.Namespace, run: RunSpec) -> list[Episode]:
    """The run's episodes: ``--episodes N`` generated with the run seed, or an episodes file checked against the
    scenes of ``--scenes``."""
    from drivenav.benchmarks.generate import generate_episodes
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import load_episodes, validate_for_scenes

    seed = run.settings.run.seed
    library = SceneLibrary(args.scenes, seed)
    if is_count(args.episodes):
        count = episode_count(int(args.episodes), "--episodes")
        return generate_episodes(library, count, seed, run.settings.sim)
    episodes = load_episodes(args.episodes)
    validate_for_scenes(episodes, library, args.episodes, run.settings.sim)
    return episodes


def scene_library(spec: EnvSpec) -> SceneLoader:
    """The scenes of an embedded spec (or of any spec derived from it), by scene id."""
    from drivenav.envs.embedded.env import EmbeddedSpec
    from drivenav.envs.embedded.library import SceneLibrary

    if not isinstance(spec, EmbeddedSpec):
        raise TypeError(f"an embedded world's spec, got {type(spec).__name__}")
    return SceneLibrary(spec.scenes, spec.seed).load


EMBEDDED = WorldEntry(
    name="embedded",
    summary="the embedded simulator",
    spec_class=_spec_class,
    build=_build,
    episodes=load_or_generate,
    label=lambda args: str(args.scenes),
    scenes=scene_library,
    embedded_episodes=True,
)
