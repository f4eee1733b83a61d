"""The fixed, versioned embedded benchmark: its definitions and their frozen episode sets."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:  # the definitions load without numpy (the command line reads them for its defaults)
    from drivenav.episode import Episode


@dataclass(frozen=True)
class BenchmarkDefinition:
    """A fixed episode set: a ``--scenes`` SPEC, an episode count, a seed and the generator (``uniform``:
    :func:`drivenav.eval.episodes.generate_episodes`; ``ovon``: HM3D-OVON's filters and splits,
    :func:`drivenav.benchmarks.ovon_episodes.generate_ovon_episodes`); once published, its episodes are frozen as a file
    shipped with drivenav (``frozen``, under ``drivenav/data``), so that no later change to the generator changes
    them."""

    scenes: str
    episodes: int
    seed: int
    frozen: str | None = None
    generator: Literal["uniform", "ovon"] = "uniform"
    cross_floor: float | None = None


BENCHMARK_V1 = BenchmarkDefinition(scenes="procedural:40,maps", episodes=200, seed=2026, frozen="benchmarks/v1.json.gz")
"""v1: 200 episodes round-robin over 40 procedural houses and the nine packaged real floor plans (a quarter by synonym),
as generated at its publication (sha256 3de8fb63...4955d8). Never change a published version; add a new one.
"""

BENCHMARK_V2 = BenchmarkDefinition(
    scenes="homes:50", episodes=300, seed=2027, frozen="benchmarks/v2.json.gz", generator="ovon"
)
"""v2: 300 episodes filtered like HM3D-OVON's (geodesic / Euclidean >= 1.05, near-straight ones thinned out, a
start with room to turn), 100 in each of its splits val_seen / val_seen_synonyms / val_unseen (episode ``i`` in
the ``i % 3``-th), over 50 homes (open-plan living areas, halls with several doors, loops through rooms), as
generated at its publication (sha256 8c08b1f3...4e6d9a).
"""

BENCHMARK_V3 = BenchmarkDefinition(
    scenes="storeys:50", episodes=300, seed=2028, generator="ovon", cross_floor=0.375, frozen="benchmarks/v3.json.gz"
)
"""v3: 300 episodes filtered and split like v2's, over 50 homes of one to three storeys joined by stairs
(:mod:`drivenav.envs.embedded.storeys`), with HM3D v1's mix: about 60 % of the episodes in multi-storey homes and,
of those, 37.5 % drawn to need a floor change (no instance of the target on the start floor), so about 22 % of all
(HM3D v1 val: 20.6 % by the goal view points' heights; ASCENT counts 28.1 % of HM3D val); docs/floors.md gives its
statistics.
"""

BENCHMARKS: dict[str, BenchmarkDefinition] = {"v1": BENCHMARK_V1, "v2": BENCHMARK_V2, "v3": BENCHMARK_V3}


def generate_benchmark(definition: BenchmarkDefinition, episodes: int | None = None) -> list[Episode]:
    """The definition's episodes, the first ``episodes`` of them if given: its frozen file where it has one, else
    generated (generation is sequential, so a prefix is the same episodes)."""
    from drivenav.benchmarks.generate import Storeys, generate_episodes
    from drivenav.benchmarks.ovon_episodes import generate_ovon_episodes
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import load_episodes
    from drivenav.types import SimConfig

    count = episodes or definition.episodes
    if definition.frozen is not None:
        with resources.as_file(resources.files("drivenav").joinpath(f"data/{definition.frozen}")) as path:
            return load_episodes(path)[:count]
    library = SceneLibrary(definition.scenes, definition.seed)
    storeys = Storeys(definition.cross_floor)
    if definition.generator == "ovon":
        return generate_ovon_episodes(library, count, definition.seed, SimConfig(), storeys=storeys)
    return generate_episodes(library, count, definition.seed, SimConfig(), storeys)
