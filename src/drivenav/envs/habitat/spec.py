"""The picklable recipe of a Habitat world (``--env habitat``), built in each worker process."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from drivenav.envs.habitat.benchmarks import BENCHMARKS, SCENES_DIR, HabitatBenchmark
from drivenav.envs.habitat.layouts import read_split
from drivenav.errors import InputError
from drivenav.types import GEODESIC, SEMANTIC, SimConfig

if TYPE_CHECKING:
    from drivenav.envs.habitat.env import HabitatEnv
    from drivenav.episode import Episode


@dataclass(frozen=True)
class HabitatSpec:
    """A benchmark preset, its split, habitat's ``data/`` folder and habitat-lab overrides (``KEY=VALUE``, applied
    last, as Hydra reads them). ``semantic`` adds habitat-lab's semantic sensor and gives agents ground-truth
    instance labels (the embedded stand-in models and ``--detector ground-truth`` need them; scenes need semantic
    annotations, as HM3D's annotated set and MP3D have). ``plugins`` are Python modules imported in every worker
    before habitat-lab's ``Env`` is built: custom simulators, sensors, measures or datasets that register
    themselves with habitat-lab's registry."""

    benchmark: str
    split: str
    data_dir: str
    overrides: tuple[str, ...] = ()
    semantic: bool = False
    plugins: tuple[str, ...] = ()
    name: ClassVar[str] = "habitat"

    @property
    def provides(self) -> frozenset[str]:
        return frozenset({GEODESIC, SEMANTIC}) if self.semantic else frozenset({GEODESIC})

    def __post_init__(self) -> None:
        if self.benchmark not in BENCHMARKS:
            raise InputError(
                "command line", "--config", f"a Habitat benchmark ({', '.join(BENCHMARKS)})", self.benchmark
            )
        splits = self.bench.splits
        if self.split not in splits:
            raise InputError(
                "command line", "--split", f"a split of {self.benchmark} ({', '.join(splits)})", self.split
            )

    @property
    def bench(self) -> HabitatBenchmark:
        return BENCHMARKS[self.benchmark]

    @property
    def split_file(self) -> Path:
        """The split's episode file under ``data_dir``."""
        return Path(self.data_dir) / self.bench.data_path.format(split=self.split)

    @property
    def scenes_dir(self) -> Path:
        """Where the scenes lie (habitat-lab's ``dataset.scenes_dir``): ``data_dir/scene_datasets``."""
        return Path(self.data_dir) / SCENES_DIR

    def episodes(self) -> list[Episode]:
        """The split's episodes in habitat-lab's order (read without habitat-lab)."""
        return read_split(self.split_file, self.bench.layout)

    def import_plugins(self) -> None:
        """Import :attr:`plugins` (a module that does not import is an :class:`InputError`)."""
        for module in self.plugins:
            try:
                importlib.import_module(module)
            except ImportError as error:
                raise InputError(
                    "command line", "--habitat-plugin", "an importable module", f"{module}: {error}"
                ) from None

    def build(self, sim: SimConfig) -> HabitatEnv:
        from drivenav.envs.habitat.env import HabitatEnv

        return HabitatEnv(self, sim)
