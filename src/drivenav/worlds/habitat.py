"""Habitat as a run sees it (``--env habitat``, docs/habitat.md): a ``--config`` benchmark, its ``--split`` and
habitat's ``--data-dir``, habitat-lab overrides (``--set habitat.KEY=VALUE``) and plugins. habitat-lab itself is
imported only in the workers that build the world."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.eval.options import is_count, path, positive
from drivenav.worlds.entry import WorldEntry

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec
    from drivenav.episode import Episode
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings

PREFIX = "habitat."  # --set habitat.KEY=VALUE: a habitat-lab override, passed through as KEY=VALUE


def _add_options(group: argparse._ArgumentGroup) -> None:
    from drivenav.envs.habitat.benchmarks import BENCHMARKS

    group.add_argument(
        "--split", default=None, help="habitat: the benchmark split (--config names the benchmark: hm3d-ovon, ...)"
    )
    group.add_argument("--data-dir", type=path, default=None, help="habitat: habitat's data/ folder")
    group.add_argument(
        "--habitat-plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="habitat: a module to import in every worker (custom simulator, sensors, datasets); repeatable",
    )
    group.set_defaults(benchmarks=sorted(BENCHMARKS))


def benchmark(args: argparse.Namespace) -> str:
    """The one Habitat benchmark among the ``--config`` presets."""
    named = [c for c in args.config if c in args.benchmarks]
    if len(named) != 1:
        expected = f"exactly one Habitat benchmark with --env habitat ({', '.join(args.benchmarks)})"
        raise InputError("command line", "--config", expected, ", ".join(named or args.config) or "none")
    return str(named[0])


def _spec_class() -> type[EnvSpec]:
    from drivenav.envs.habitat.spec import HabitatSpec

    return HabitatSpec


def _build(args: argparse.Namespace, settings: Settings) -> EnvSpec:
    """The Habitat world of ``--config BENCHMARK --split --data-dir``; a semantic sensor where the agent's models
    need ground-truth labels."""
    from drivenav.agents import make_agent
    from drivenav.envs.habitat.config import check_habitat_config
    from drivenav.envs.habitat.spec import HabitatSpec
    from drivenav.types import SEMANTIC

    for option, value in (("--split", args.split), ("--data-dir", args.data_dir)):
        if value is None:
            raise InputError("command line", option, "a value with --env habitat (see docs/habitat.md)")
    if not args.data_dir.is_dir():
        raise InputError(
            "command line", "--data-dir", "habitat's data/ folder (datasets/, scene_datasets/)", args.data_dir
        )
    overrides = tuple(o for o in args.overrides if o.startswith(PREFIX))
    semantic = SEMANTIC in make_agent(settings).requires
    data_dir = str(args.data_dir.resolve())
    spec = HabitatSpec(benchmark(args), args.split, data_dir, overrides, semantic, tuple(args.habitat_plugin))
    check_habitat_config(spec, settings.sim)
    return spec


def _episodes(args: argparse.Namespace, run: RunSpec) -> list[Episode]:
    """The split's first ``--episodes N``, or ``all``."""
    from drivenav.envs.habitat.spec import HabitatSpec

    if not isinstance(run.env, HabitatSpec):
        raise TypeError(f"a Habitat spec, got {type(run.env).__name__}")
    episodes = run.env.episodes()
    if str(args.episodes) == "all":
        return episodes
    if not is_count(args.episodes):
        raise InputError("command line", "--episodes", "N (the split's first N episodes) or all", args.episodes)
    return episodes[: positive(int(args.episodes), "--episodes")]


HABITAT = WorldEntry(
    name="habitat",
    summary="Habitat",
    spec_class=_spec_class,
    build=_build,
    episodes=_episodes,
    label=lambda args: f"{benchmark(args)} {args.split}",
    add_options=_add_options,
    own_options=("--split", "--data-dir"),
    docs="see docs/habitat.md",
    set_prefix=PREFIX,
    presets=lambda args: [benchmark(args)],  # the benchmark's settings (success distance, ...) under every layer
    needs_benchmark=True,
)
