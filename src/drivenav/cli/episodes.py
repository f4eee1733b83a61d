"""Episode files: ``episodes generate`` (HM3D-OVON-style episodes over embedded scenes), ``episodes export``
(an episodes file in a Habitat dataset layout) and ``episodes stats`` (the world and episode statistics of
docs/world-vs-hm3d.md)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, NoReturn

from drivenav.cli.common import Commands
from drivenav.errors import InputError
from drivenav.eval.options import episode_count, path, seed

if TYPE_CHECKING:
    from tqdm import tqdm

    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.episode import Episode


def add_episodes(commands: Commands) -> None:
    from drivenav.benchmarks.benchmark import BENCHMARKS
    from drivenav.envs.habitat.benchmarks import LAYOUTS

    parser = commands.add_parser("episodes", help="episode files")
    sub = parser.add_subparsers(dest="episodes_command", required=True)
    generate = sub.add_parser("generate", help="generate HM3D-OVON-style episodes (json.gz)")
    generate.add_argument(
        "--scenes", default="procedural", help="a --scenes SPEC (storeys[:K]: homes of several floors)"
    )
    generate.add_argument("--num", type=int, required=True)
    generate.add_argument("--seed", type=int, default=0)
    generate.add_argument("--out", type=path, required=True)
    generate.add_argument(
        "--cross-floor",
        type=str,
        metavar="SHARE",
        help="in scenes of several storeys, the share of episodes (0 to 1) whose target has no instance on the start "
        "floor, so that the agent must change floors (default: starts on any floor)",
    )
    generate.set_defaults(handler=_cmd_episodes_generate)
    export = sub.add_parser("export", help="write an episodes file in a Habitat layout (ObjectNav v1 or HM3D-OVON)")
    export.add_argument("--episodes", required=True, type=path, help="an episodes file (drivenav's json.gz)")
    export.add_argument("--format", required=True, choices=LAYOUTS, help="the Habitat dataset layout")
    export.add_argument("--split", default="val", help="the split's name (default val)")
    export.add_argument("--out", required=True, type=path, help="the dataset folder: writes OUT/SPLIT/SPLIT.json.gz")
    export.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an earlier export of the split in OUT/SPLIT (without it such a folder is refused)",
    )
    export.set_defaults(handler=_cmd_episodes_export)
    stats = sub.add_parser("stats", help="doors, loops, rooms and area of the scenes; distances of the episodes")
    benchmarks = ", ".join(BENCHMARKS)
    stats.add_argument(
        "episodes",
        metavar="EPISODES",
        help=f"an episodes file, a Habitat split file with --format, or a benchmark name ({benchmarks})",
    )
    stats.add_argument(
        "--format",
        choices=LAYOUTS,
        help="read EPISODES as a split file in this Habitat layout ({split}/{split}.json.gz and its content/ "
        "files, as --env habitat reads them; HM3D's own ObjectNav v1 splits among them)",
    )
    stats.add_argument(
        "--scenes",
        help=f"a --scenes SPEC with the episodes' scenes (default: the benchmark's, else {_STATS_SCENES})",
    )
    stats.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    stats.add_argument(
        "--no-check",
        action="store_true",
        help="measure an episodes file as it is, without first checking it against the scenes as eval does "
        "(starts on navigable floor, goals reachable, info.geodesic_distance within 10 %%); says so on stderr",
    )
    stats.set_defaults(handler=_cmd_episodes_stats)


_STATS_SCENES = "procedural,homes,storeys,maps"
"""Where ``episodes stats`` loads an episodes file's scenes from by default: procedural houses, homes and homes of
several storeys (any of them, by id) and the packaged floor plans."""


def _cmd_episodes_generate(args: argparse.Namespace) -> int:
    from drivenav.benchmarks.generate import Storeys, generate_episodes
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import save_episodes
    from drivenav.types import SimConfig

    count = episode_count(args.num, "--num")
    storeys = Storeys(None if args.cross_floor is None else share(args.cross_floor, "--cross-floor"))
    library = SceneLibrary(args.scenes, seed(args.seed))
    episodes = generate_episodes(library, count, args.seed, SimConfig(), storeys)
    save_episodes(episodes, args.out)
    synonyms = sum(bool(e.info.get("synonym")) for e in episodes)
    scenes = len({e.scene_id for e in episodes})
    cross = sum(e.info.get("cross_floor") is True for e in episodes)
    floors = f", {cross} needing a floor change" if any("cross_floor" in e.info for e in episodes) else ""
    print(f"wrote {len(episodes)} episodes over {scenes} scenes ({synonyms} by synonym{floors}) to {args.out}")
    return 0


def share(text: str, option: str) -> float:
    """A share from the command line: a number from 0 to 1 (one line and exit 2 otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value <= 1.0:
        raise InputError("command line", option, "a share from 0 to 1", text)
    return value


def _cmd_episodes_export(args: argparse.Namespace) -> int:
    from drivenav.envs.habitat.layouts import export_split
    from drivenav.eval.episodes import load_episodes

    episodes = load_episodes(args.episodes)
    split = str(args.split)
    if not split or "/" in split or split.startswith("."):
        raise InputError("command line", "--split", "a split name such as val", split)
    written = export_split(episodes, args.out / split, args.format, args.episodes, overwrite=args.overwrite)
    print(f"wrote {len(episodes)} episodes as {args.format} to {written[0]} and {len(written) - 1} content files")
    return 0


def _cmd_episodes_stats(args: argparse.Namespace) -> int:
    import json

    from drivenav.benchmarks.world_stats import measure
    from drivenav.benchmarks.world_stats_table import format_world_stats

    episodes, library = _stats_input(args)
    with progress("measuring", len(episodes)) as bar:
        stats = measure(episodes, library, source=str(args.episodes), measured_one=bar.update)
    print(json.dumps(stats.to_json(), indent=1) if args.json else format_world_stats(stats))
    return 0


def _stats_input(args: argparse.Namespace) -> tuple[list[Episode], SceneLibrary]:
    """The episodes ``episodes stats`` measures and the scenes they use: a benchmark's, or a file's checked against
    the scenes unless ``--no-check``."""
    import sys
    from pathlib import Path

    from drivenav.benchmarks.benchmark import BENCHMARKS, generate_benchmark
    from drivenav.benchmarks.world_stats import StatsConfig
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import validate_for_scenes

    name = str(args.episodes)
    benchmark = BENCHMARKS.get(name) if not Path(name).exists() and args.format is None else None
    if benchmark is not None:
        return generate_benchmark(benchmark), SceneLibrary(args.scenes or benchmark.scenes, benchmark.seed)
    episodes, library = _stats_file(name, args.format), SceneLibrary(args.scenes or _STATS_SCENES)
    if args.no_check:
        print(
            f"drivenav: {name} not checked against the scenes (--no-check): figures as the file gives them",
            file=sys.stderr,
        )
    else:
        with progress("checking", len(episodes)) as bar:
            validate_for_scenes(episodes, library, name, StatsConfig().sim, checked_one=bar.update)
    return episodes, library


def _stats_file(name: str, layout: str | None) -> list[Episode]:
    """The episodes of drivenav's own episodes file, or of a Habitat split file in ``layout`` (``--format``)."""
    from pathlib import Path

    from drivenav.benchmarks.benchmark import BENCHMARKS
    from drivenav.envs.habitat.layouts import read_split
    from drivenav.eval.episodes import load_episodes

    if layout is not None:
        return read_split(Path(name), layout)
    if not Path(name).is_file():
        expected = f"an episodes file or a benchmark name ({', '.join(BENCHMARKS)})"
        raise InputError("command line", "EPISODES", expected, name)
    with progress("reading", None) as bar:
        return load_episodes(name, read_one=bar.update)


def progress(stage: str, total: int | None) -> tqdm[NoReturn]:
    """A progress line of ``episodes stats`` (episodes read, checked, measured: a million episodes take minutes) on
    standard error, and only where it is a terminal (tqdm's ``disable=None``): never in stdout's table or JSON, nor
    in a log."""
    from tqdm import tqdm

    return tqdm(total=total, desc=f"episodes stats: {stage}", unit="ep", disable=None, mininterval=1.0, leave=False)
