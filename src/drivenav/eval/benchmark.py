"""The fixed, versioned embedded benchmark: its definitions and their frozen episode sets."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the definitions load without numpy (the command line reads them for its defaults)
    from drivenav.episode import Episode


@dataclass(frozen=True)
class BenchmarkDefinition:
    """A fixed episode set: a ``--scenes`` SPEC, an episode count and a seed; once
    published, its episodes are frozen as a file shipped with drivenav (``frozen``, under ``drivenav/data``), so
    that no later change to the generator changes them."""

    scenes: str
    episodes: int
    seed: int
    frozen: str | None = None


BENCHMARK_V1 = BenchmarkDefinition(scenes="procedural:40,maps", episodes=200, seed=2026, frozen="benchmarks/v1.json.gz")
"""v1: 200 episodes round-robin over 40 procedural houses and the nine packaged real floor plans (a quarter by synonym),
as generated at its publication (sha256 3de8fb63...4955d8). Never change a published version; add a new one.
"""

BENCHMARKS: dict[str, BenchmarkDefinition] = {"v1": BENCHMARK_V1}


def generate_benchmark(definition: BenchmarkDefinition, episodes: int | None = None) -> list[Episode]:
    """The definition's episodes, the first ``episodes`` of them if given: its frozen file where it has one, else
    generated (generation is sequential, so a prefix is the same episodes)."""
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import generate_episodes, load_episodes
    from drivenav.types import SimConfig

    count = episodes or definition.episodes
    if definition.frozen is not None:
        with resources.as_file(resources.files("drivenav").joinpath(f"data/{definition.frozen}")) as path:
            return load_episodes(path)[:count]
    library = SceneLibrary(definition.scenes, definition.seed)
    return generate_episodes(library, count, definition.seed, SimConfig())
