"""Running agents: ``eval`` (a run directory over any world), ``run`` (one live episode on a robot), ``config
show``, ``compare``, ``viz``, ``demo`` and ``doctor``."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from drivenav.cli.common import (
    Commands,
    add_config_options,
    add_execution_options,
    add_floor_reference,
    add_max_steps,
    add_model_options,
    add_run_seed,
    add_world_options,
    episodes,
    executor,
    floor_reference,
    given_options,
    run_spec,
    settings,
    world_label,
)
from drivenav.errors import InputError
from drivenav.eval.options import path, positive
from drivenav.worlds import DEFAULT_WORLD, WORLDS, chosen_world, world_named


def add_eval(commands: Commands) -> None:
    from drivenav.methods import agent_names

    parser = commands.add_parser("eval", help="run an agent on episodes and write metrics")
    parser.add_argument("--agent", required=True, help=f"agent name ({', '.join(agent_names())})")
    parser.add_argument(
        "--scenes", default="procedural", help="procedural[:K], homes[:K], maps, a scene dir, or a folder of them"
    )
    parser.add_argument(
        "--episodes",
        required=True,
        help="embedded: a number of episodes to generate, or an episodes file; habitat: N (the split's first) or all",
    )
    add_run_seed(parser)
    parser.add_argument("--out", required=True, type=path, help="run directory (rerun to resume)")
    add_max_steps(parser)
    add_execution_options(parser)
    parser.add_argument(
        "--share-detector",
        action="store_true",
        help="one copy of the detector for every worker: served on a free loopback port for the run (--detector "
        "remote for the workers; the server's log is DIR/grounder-server.log)",
    )
    add_model_options(parser)
    add_config_options(parser)
    parser.set_defaults(handler=_cmd_eval)
    add_world_options(parser)  # last: a plug-in world's options are checked against every other option


def add_run(commands: Commands) -> None:
    robot = world_named("robot")
    parser = commands.add_parser("run", help="one live episode on a robot (docs/robot.md)")
    parser.add_argument("--env", default=robot.name, choices=(robot.name,), help="the world: a robot")
    parser.add_argument("--target", required=True, help='what to find, e.g. "fire extinguisher"')
    parser.add_argument("--agent", default="drive-nav", help="agent name (default drive-nav)")
    parser.add_argument("--out", type=path, default=None, help="run directory (default runs/live-DATE-TIME)")
    parser.add_argument(
        "--episode-id", default=None, help="the episode id sent with RESET (serve-sim: one of its episodes)"
    )
    add_max_steps(parser)
    add_run_seed(parser)
    robot.add_options(parser.add_argument_group("robot"))
    add_model_options(parser)
    add_config_options(parser)
    parser.set_defaults(handler=_cmd_run)


def add_config(commands: Commands) -> None:
    from drivenav.methods import agent_names

    parser = commands.add_parser("config", help="the configuration tree")
    sub = parser.add_subparsers(dest="config_command", required=True)
    show = sub.add_parser("show", help="print the resolved configuration as YAML (loads back with --config)")
    show.add_argument("--agent", default=None, help=f"apply this method's preset ({', '.join(agent_names())})")
    add_config_options(show)
    show.set_defaults(handler=_cmd_config_show)


def add_viz(commands: Commands) -> None:
    parser = commands.add_parser("viz", help="pictures of a finished episode (a building's: a top-down map per floor)")
    parser.add_argument("run_dir", type=path)
    parser.add_argument("episode_id")
    parser.add_argument("--out", type=path, default=None, help="output folder (default RUN_DIR/viz)")
    parser.add_argument("--rerun", action="store_true", help="also a Rerun recording (.rrd) of the same streams")
    parser.set_defaults(handler=_cmd_viz)


def add_compare(commands: Commands) -> None:
    parser = commands.add_parser("compare", help="compare runs; steps and revisits on commonly solved long episodes")
    parser.add_argument("run_dirs", type=path, nargs="+")
    parser.add_argument("--min-distance", type=float, default=10.0, help="Table II: geodesic distance above this")
    parser.add_argument("--json", action="store_true")
    add_floor_reference(parser, "RUN", "the run (by folder name)")
    parser.set_defaults(handler=_cmd_compare)


def add_demo(commands: Commands) -> None:
    parser = commands.add_parser("demo", help="a short embedded benchmark with pictures")
    parser.add_argument("--out", type=path, default=Path("demo-output"))
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    parser.set_defaults(handler=_cmd_demo)


def add_doctor(commands: Commands) -> None:
    from drivenav.envs.habitat.benchmarks import BENCHMARKS

    parser = commands.add_parser("doctor", help="check a Habitat / VLM / segmenter set-up before a long run")
    parser.add_argument("--env", default=DEFAULT_WORLD, choices=WORLDS.names)
    parser.add_argument("--config", default=None, choices=sorted(BENCHMARKS), help="with --env habitat: benchmark")
    parser.add_argument("--split", default=None, help="one split (default: every split of the benchmark)")
    parser.add_argument("--data-dir", type=path, default=None, help="habitat's data/ folder")
    add_model_options(parser)
    parser.set_defaults(handler=_cmd_doctor)


def _cmd_eval(args: argparse.Namespace) -> int:
    from drivenav.eval.report import format_table
    from drivenav.eval.rundir import EPISODES_FILE, SUMMARY_FILE, make_directory, refuse_missing_explorer
    from drivenav.eval.runner import evaluate

    refuse_missing_explorer(args.out)  # a resume of a plug-in's run once it is uninstalled: what to install
    pool = executor(args)
    spec = run_spec(args, args.agent, connect=not args.share_detector)  # an unknown agent or setting fails first
    if args.share_detector:
        from drivenav.eval.shared_detector import check_shareable

        check_shareable(spec.settings.models, pool)
    make_directory(args.out)
    if args.share_detector:
        from drivenav.eval.shared_detector import shared_detector

        with shared_detector(spec.settings.models, args.out) as served:
            summary = evaluate(episodes(args, spec), spec, args.out, pool, served=served)
    else:
        summary = evaluate(episodes(args, spec), spec, args.out, pool)
    print(format_table(summary, f"{args.agent} on {world_label(args)}"))
    print(f"results: {args.out / EPISODES_FILE}  summary: {args.out / SUMMARY_FILE}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    import time

    from drivenav.brain.live import run_live

    if not args.target.strip():
        raise InputError("command line", "--target", "the object to find, e.g. 'fire extinguisher'", args.target)
    spec = run_spec(args, args.agent)
    out = args.out or Path("runs") / time.strftime("live-%Y%m%d-%H%M%S")
    record, picture = run_live(spec, args.target, out, args.episode_id)
    print(f"{record.stop_reason} after {record.steps} steps{': ' + record.error if record.error else ''}")
    print(f"run: {out}  picture: {picture or 'none (the episode ended before it started)'}")
    return 1 if record.error else 0


def _cmd_config_show(args: argparse.Namespace) -> int:
    from drivenav.agents import check_parts
    from drivenav.settings import settings_to_yaml

    resolved = settings(args, args.agent)
    check_parts(resolved)
    print(settings_to_yaml(resolved), end="")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from drivenav.analysis.floor_compare import compare_with_floors, comparison_json, format_compare

    if not (math.isfinite(args.min_distance) and args.min_distance >= 0.0):
        raise InputError("command line", "--min-distance", "a distance in metres >= 0", args.min_distance)
    dirs = {}
    for run_dir in args.run_dirs:
        if not (run_dir / "episodes.jsonl").is_file():
            raise InputError(run_dir, "RUN_DIR", "a run directory written by 'drivenav eval'")
        dirs[run_dir.name] = run_dir
    reference = floor_reference(args, list(dirs), "the name of one of the RUN_DIRs")
    result, floors = compare_with_floors(dirs, args.min_distance, reference)
    if len(dirs) > 1 and result.shared_episodes == 0:
        raise InputError("command line", "RUN_DIR", "runs over the same episodes (these share none)")
    print(json.dumps(comparison_json(result, floors)) if args.json else format_compare(result, floors))
    return 0


def _cmd_viz(args: argparse.Namespace) -> int:
    from drivenav.viz.episode import load_episode, render_episode_pictures

    material = load_episode(args.run_dir, args.episode_id)
    paths = render_episode_pictures(material, args.out or args.run_dir / "viz", rerun=args.rerun)
    for written in paths:
        print(written)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from drivenav.demo import DEMO_AGENTS, run_demo
    from drivenav.report.site import write_report

    index = run_demo(args.out, positive(args.episodes, "--episodes"), args.seed)
    site = write_report([args.out / agent for agent, _ in DEMO_AGENTS], args.out / "report")
    print(f"demo results and pictures: {args.out.resolve()}  (start with {index}, or {site.resolve()} in a browser)")
    return 0


def _cmd_doctor(args: argparse.Namespace) -> int:
    from drivenav.doctor import DoctorRequest, format_checks, run_checks
    from drivenav.settings import load_settings

    models = load_settings(options=given_options(args)).models
    world = chosen_world(args)
    if world.needs_benchmark and args.config is None:
        raise InputError("command line", "--config", f"a Habitat benchmark with --env {world.name}", None)
    benchmark = str(args.config) if world.needs_benchmark else ""
    checks = run_checks(DoctorRequest(models, benchmark, args.data_dir, args.split))
    print(format_checks(checks))
    return 0 if all(check.ok for check in checks) else 1


RESUMABLE = (_cmd_eval, _cmd_demo)
"""The handlers that write run directories episode by episode (rerun to resume)."""
