"""What several commands share: the configuration, model and execution options, the resolved settings, the run's
world (``--env``: its options, spec, episodes and title, all through :data:`drivenav.worlds.WORLDS`) and
printing a benchmark's result."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeAlias

from drivenav.errors import InputError
from drivenav.eval.options import seed
from drivenav.jsonstream import JsonObject
from drivenav.plugins import add_options_of
from drivenav.worlds import DEFAULT_WORLD, WORLDS, WorldEntry, chosen_world, offered_worlds, usable_worlds

if TYPE_CHECKING:
    from drivenav.episode import Episode
    from drivenav.eval.executor import Executor
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings

Handler = Callable[[argparse.Namespace], int]
Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"  # a parser's sub-commands (no public name)

OPTION_KEYS = {
    "seed": "run.seed",
    "max_steps": "sim.max_steps",
    "reasoner": "models.reasoner",
    "detector": "models.detector",
    "vlm_base_url": "models.vlm_base_url",
    "vlm_model": "models.vlm_model",
    "vlm_record": "models.vlm_record",
    "vlm_replay": "models.vlm_replay",
    "detector_model": "models.detector_model",
    "scorer": "models.scorer",
    "scorer_model": "models.scorer_model",
    "dtype": "models.dtype",
    "detector_url": "models.detector_url",
    "detector_keys": "models.detector_keys",
    "segmenter": "models.segmenter",
    "segmenter_model": "models.segmenter_model",
    "compile": "models.compile",
    "detector_shadow_url": "models.detector_shadow_url",
    "detector_regime": "models.detector_regime",
}
"""The dedicated options that set a settings key (``--seed`` -> ``run.seed``, ...)."""


def add_max_steps(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--max-steps", type=int, default=None, help="step budget (default 500; sets sim.max_steps)")


def add_run_seed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=None, help="run seed (default 0; sets run.seed)")


def add_floor_reference(parser: argparse.ArgumentParser, metavar: str, what: str) -> None:
    parser.add_argument(
        "--floor-reference",
        default=None,
        metavar=metavar,
        help=f"floor groups (episodes with info.cross_floor): {what} the others' wins / losses are counted against, "
        "e.g. a floors-off variant (default: drive-nav)",
    )


def floor_reference(args: argparse.Namespace, names: Sequence[str], expected: str) -> str:
    """``--floor-reference``: one of ``names`` where given, else the default reference of the pairings
    (``drive-nav``, which need not have been run: then nothing is paired)."""
    from drivenav.analysis.paper_tables import PAIRED_REFERENCE

    if args.floor_reference is None:
        return PAIRED_REFERENCE
    if args.floor_reference not in names:
        raise InputError("command line", "--floor-reference", expected, args.floor_reference)
    return str(args.floor_reference)


def add_config_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.methods import preset_names

    group = parser.add_argument_group("configuration (see 'drivenav config show')")
    group.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="NAME_OR_FILE",
        help=f"a preset ({', '.join(preset_names())}) or a YAML file; repeatable, later ones win",
    )
    group.add_argument(
        "--set",
        action="append",
        default=[],
        dest="overrides",
        metavar="KEY=VALUE",
        help="a dotted override, e.g. paper.speed.lam=0.5 (habitat.KEY=VALUE: a habitat-lab override); repeatable",
    )


def add_model_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.semantics.model_spec import DETECTOR_REGIMES, DTYPES, ModelSpec
    from drivenav.semantics.registry import GROUNDER_BACKENDS, REASONER_BACKENDS, SCORER_BACKENDS

    default = ModelSpec()
    models = parser.add_argument_group(
        "models (reasoner = the VLM's role, detector = SAM3's role, scorer = VLFM's BLIP-2; sets models.*)"
    )
    models.add_argument("--reasoner", help=f"one of {', '.join(REASONER_BACKENDS.names)} (default {default.reasoner})")
    models.add_argument("--detector", help=f"one of {', '.join(GROUNDER_BACKENDS.names)} (default {default.detector})")
    models.add_argument(
        "--detector-regime",
        help=f"with --detector embedded, its preset: one of {', '.join(DETECTOR_REGIMES)} (default "
        f"{default.detector_regime}; docs/regimes.md)",
    )
    scorers = ", ".join(SCORER_BACKENDS.names)
    models.add_argument(
        "--scorer", help=f"the vlfm method's image-text scorer: one of {scorers} (default {default.scorer})"
    )
    models.add_argument("--vlm-base-url", help=f"OpenAI-compatible endpoint (default {default.vlm_base_url})")
    models.add_argument("--vlm-model", help=f"default {default.vlm_model}")
    models.add_argument("--vlm-record", help="record every reasoner and scorer request/answer to this file")
    models.add_argument("--vlm-replay", help="with --reasoner replay or --scorer replay: answer from this recording")
    models.add_argument("--detector-model", help="local checkpoint dir or HF-cache model id")
    models.add_argument(
        "--dtype",
        help=f"the detector's weights: one of {', '.join(DTYPES)} (default {default.dtype}: bf16 on CUDA, else fp32)",
    )
    models.add_argument("--scorer-model", help="local checkpoint dir or HF-cache model id (default: the scorer's own)")
    models.add_argument(
        "--detector-url",
        help=f"with --detector remote: a 'drivenav serve grounder' endpoint (default {default.detector_url})",
    )
    models.add_argument("--detector-keys", help="with --detector remote off loopback: the CURVE key folder")
    add_segmenter_options(models)
    models.add_argument(
        "--compile",
        action="store_true",
        default=None,
        help="torch.compile the transformers models' per-frame modules (sets models.compile; compiled at first use)",
    )
    models.add_argument(
        "--detector-shadow-url",
        help="a 'drivenav serve grounder' endpoint sent every frame the detector grounds, its answer discarded: a "
        "served model's cost beside --detector's detections (throughput benchmarks with random weights)",
    )


def add_segmenter_options(group: argparse._ArgumentGroup | argparse.ArgumentParser, own_defaults: bool = False) -> None:
    """``--segmenter`` and ``--segmenter-model``: unset unless given (a run's settings decide), or with
    ``own_defaults`` the settings' defaults (a command that reads no settings)."""
    from drivenav.semantics.registry import BOX_DETECTORS, DEFAULT_SEGMENTER, SEGMENTER_BACKENDS

    group.add_argument(
        "--segmenter",
        choices=SEGMENTER_BACKENDS.names,
        default=DEFAULT_SEGMENTER if own_defaults else None,
        help=f"what turns the boxes of {' and '.join(BOX_DETECTORS)} into masks (default {DEFAULT_SEGMENTER}: the "
        "box filled; mobilesam: MobileSAM's mask in the box)",
    )
    group.add_argument(
        "--segmenter-model",
        default="" if own_defaults else None,
        help="with --segmenter mobilesam: its checkpoint file (mobile_sam.pt)",
    )


def add_execution_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.eval.executor import EXECUTORS

    parser.add_argument(
        "--workers", type=int, default=None, help="parallel workers (default: 1 local, every CPU of a Ray cluster)"
    )
    parser.add_argument("--executor", default="local", choices=EXECUTORS, help="local processes or Ray tasks")
    parser.add_argument("--ray-address", default=None, help="a Ray cluster (default: a private local instance)")


def add_world_options(parser: argparse.ArgumentParser) -> None:
    """``--env`` and every world's own options, in one group titled with the worlds' documentation (a plug-in world
    that cannot be loaded, or whose options do not fit the command, is still a choice, refused with its one line when
    chosen). Called once the command's other options are in: a plug-in's options are checked against them all."""
    worlds = usable_worlds()
    docs = "; ".join(f"--env {world.name}: {world.docs}" for world in worlds if world.docs)
    names = [world.summary for world in worlds]
    group = parser.add_argument_group(f"world ({docs})")
    summary = f"{', '.join(names[:-1])} or {names[-1]}" if len(names) > 1 else names[0]
    group.add_argument("--env", default=DEFAULT_WORLD, choices=WORLDS.names, help=summary)
    add_options_of(parser, group, WORLDS, {world.name: world.add_options for world in worlds})


def executor(args: argparse.Namespace) -> Executor:
    from drivenav.eval.executor import Executor

    return Executor(args.executor, args.workers, args.ray_address)


def given_options(args: argparse.Namespace) -> dict[str, object]:
    """The dedicated options given on the command line, as settings keys (``--seed`` -> ``run.seed``, ...)."""
    return {key: getattr(args, name) for name, key in OPTION_KEYS.items() if getattr(args, name, None) is not None}


def settings(args: argparse.Namespace, agent: str | None) -> Settings:
    """The resolved configuration: defaults, the world's presets (a Habitat benchmark's, first, under every other
    layer), ``agent``'s preset, ``--config``, the options given, ``--set`` (less the worlds' own overrides)."""
    from drivenav.settings import load_settings

    given = given_options(args)
    for key in ("models.vlm_record", "models.vlm_replay", "models.detector_keys", "models.segmenter_model"):
        if given.get(key):
            given[key] = str(Path(str(given[key])).resolve())
    if "run.seed" in given:
        seed(int(str(given["run.seed"])))
    world = chosen_world(args)
    with WORLDS.guard(world.name, "presets"):
        presets = world.presets(args)
    configs = [*presets, *(c for c in args.config if c not in presets)]
    prefixes = tuple(world.set_prefix for world in offered_worlds(args) if world.set_prefix)
    overrides = [o for o in args.overrides if not (prefixes and o.startswith(prefixes))]
    return load_settings(agent, configs=configs, overrides=overrides, options=given)


def check_world_options(args: argparse.Namespace, world: WorldEntry) -> None:
    """A world's own options only with that world (before any model loads)."""
    for other in offered_worlds(args):
        if other is not world:
            other.refuse_options(args)


def run_spec(args: argparse.Namespace, agent: str, connect: bool = True) -> RunSpec:
    """The world (``--env``) and the resolved settings for ``agent``; models are checked before any work (with
    ``connect=False`` the cheap checks only: a shared detector's server loads its model)."""
    from drivenav.eval.runner import RunSpec
    from drivenav.semantics.registry import check_models

    world = chosen_world(args)
    check_world_options(args, world)
    resolved = settings(args, agent)
    check_models(resolved.models, connect)
    with WORLDS.guard(world.name, "build"):
        env = world.build(args, resolved)
    return RunSpec(env, resolved)


def episodes(args: argparse.Namespace, spec: RunSpec) -> list[Episode]:
    """The run's episodes, from its world's source (generated, a file, a Habitat split)."""
    world = chosen_world(args)
    with WORLDS.guard(world.name, "episodes"):
        found = world.episodes(args, spec)
    return found


def world_label(args: argparse.Namespace) -> str:
    """What a run's table is titled with: the scenes, the benchmark and split, the robot."""
    world = chosen_world(args)
    with WORLDS.guard(world.name, "label"):
        label = world.label(args)
    return label


def print_bench(result: JsonObject, as_json: bool) -> int:
    """A benchmark's result: one JSON object, or one aligned ``key: value`` line each."""
    if as_json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:>20}: {value}")
    return 0
