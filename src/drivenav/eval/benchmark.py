"""The fixed, versioned embedded benchmark: its definitions and their frozen episode sets."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING

from drivenav.errors import InputError

if TYPE_CHECKING:  # the definitions load without numpy (the command line reads them for its defaults)
    from drivenav.envs.episode import Episode

SHARED_MAPS = "{shared_maps}"  # stands for drivenav.envs.rosmap.default_shared_maps_dir() in a scenes SPEC


@dataclass(frozen=True)
class BenchmarkDefinition:
    """A fixed episode set: a ``--scenes`` SPEC (may name ``{shared_maps}``), an episode count and a seed; once
    published, its episodes are frozen as a file shipped with drivenav (``frozen``, under ``drivenav/data``), so
    that no later change to the generator changes them."""

    scenes: str
    episodes: int
    seed: int
    frozen: str | None = None


BENCHMARK_V1 = BenchmarkDefinition(
    scenes=f"procedural:40,{SHARED_MAPS}", episodes=200, seed=2026, frozen="benchmarks/v1.json.gz"
)
"""v1: 200 episodes round-robin over 40 procedural houses and every shared real floor plan (a quarter by synonym),
as generated at its publication (sha256 3de8fb63...4955d8). Never change a published version; add a new one.
"""

BENCHMARKS: dict[str, BenchmarkDefinition] = {"v1": BENCHMARK_V1}


def resolve_scenes(spec: str) -> str:
    """``spec`` with ``{shared_maps}`` replaced by the shared floor plans folder (an error if there is none)."""
    if SHARED_MAPS not in spec:
        return spec
    from drivenav.envs.rosmap import default_shared_maps_dir

    maps = default_shared_maps_dir()
    if maps is None:
        raise InputError("DRIVENAV_SHARED", "--scenes", "a shared folder holding data/maps (the real floor plans)")
    return spec.replace(SHARED_MAPS, str(maps))


def generate_benchmark(definition: BenchmarkDefinition, episodes: int | None = None) -> list[Episode]:
    """The definition's episodes, the first ``episodes`` of them if given: its frozen file where it has one, else
    generated (generation is sequential, so a prefix is the same episodes)."""
    from drivenav.envs.library import SceneLibrary
    from drivenav.eval.episodes import generate_episodes, load_episodes
    from drivenav.types import SimConfig

    count = episodes or definition.episodes
    if definition.frozen is not None:
        with resources.as_file(resources.files("drivenav").joinpath(f"data/{definition.frozen}")) as path:
            return load_episodes(path)[:count]
    library = SceneLibrary(resolve_scenes(definition.scenes), definition.seed)
    return generate_episodes(library, count, definition.seed, SimConfig())
