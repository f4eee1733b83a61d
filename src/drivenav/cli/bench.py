"""Speed benchmarks and the paper's tables: ``bench sim|directions|mapping|agent|episodes|robot|grounder`` (one
figure each, or one JSON object), ``bench ablations`` (Tables II, V, VI, VII) and ``benchmark generate`` (the fixed,
versioned embedded benchmark)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.cli.common import (
    Commands,
    add_config_options,
    add_execution_options,
    add_floor_reference,
    add_max_steps,
    add_model_options,
    add_segmenter_options,
    add_world_options,
    episodes,
    executor,
    floor_reference,
    print_bench,
    run_spec,
)
from drivenav.errors import InputError
from drivenav.eval.options import episode_count, is_count, path, positive
from drivenav.methods import ALL_METHODS, METHOD_NAMES
from drivenav.worlds import chosen_world

if TYPE_CHECKING:
    from drivenav.benchmarks.benchmark import BenchmarkDefinition
    from drivenav.episode import Episode
    from drivenav.semantics.grounder_bench import GrounderBenchOptions


def add_bench(commands: Commands) -> None:
    from drivenav.benchmarks.benchmark import BENCHMARKS

    parser = commands.add_parser("bench", help="speed benchmarks")
    sub = parser.add_subparsers(dest="bench_command", required=True)
    sim = sub.add_parser("sim", help="embedded simulator frames per second (RGB + depth + semantic, one core)")
    sim.add_argument("--frames", type=int, default=300)
    sim.add_argument(
        "--scene",
        metavar="SCENE_ID",
        help="a generated scene by id, e.g. storeys/home_00004 (a home of three storeys); default: procedural house 0",
    )
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.set_defaults(handler=_cmd_bench_sim)
    directions = sub.add_parser("directions", help="map -> labelled directions for all frontiers (480x480 map)")
    directions.add_argument("--repeats", type=int, default=50)
    directions.add_argument("--json", action="store_true", help="print one JSON object")
    directions.set_defaults(handler=_cmd_bench_directions)
    mapping = sub.add_parser("mapping", help="mapping update per 640x480 depth frame, frontier extraction")
    mapping.add_argument("--frames", type=int, default=24)
    mapping.add_argument("--json", action="store_true", help="print one JSON object")
    mapping.set_defaults(handler=_cmd_bench_mapping)
    agent = sub.add_parser("agent", help="agent compute per step (models excluded) and per-module breakdown")
    agent.add_argument("--episodes", type=int, default=4)
    agent.add_argument("--max-steps", type=int, default=150)
    agent.add_argument(
        "--agent", default="drive-nav", choices=METHOD_NAMES, help="the method timed (default drive-nav)"
    )
    agent.add_argument(
        "--benchmark", default=None, choices=sorted(BENCHMARKS), help="its first episodes (default: procedural houses)"
    )
    agent.add_argument("--json", action="store_true", help="print one JSON object")
    agent.set_defaults(handler=_cmd_bench_agent)
    _add_bench_ablations(sub)
    stream = sub.add_parser("episodes", help="a large episodes file: read, check, digest, copy, memory per episode")
    stream.add_argument("--num", type=int, default=100_000)
    stream.add_argument("--json", action="store_true", help="print one JSON object")
    stream.set_defaults(handler=_cmd_bench_episodes)
    robot = sub.add_parser("robot", help="robot protocol round trip of one 640x480 observation, plain and CURVE")
    robot.add_argument("--repeats", type=int, default=200)
    robot.add_argument("--json", action="store_true", help="print one JSON object")
    robot.set_defaults(handler=_cmd_bench_robot)
    _add_bench_grounder(sub)
    _add_bench_eval_throughput(sub)


def _add_bench_ablations(sub: Commands) -> None:
    from drivenav.benchmarks.benchmark import BENCHMARKS

    parser = sub.add_parser("ablations", help="the paper's Tables II, V, VI and VII on the embedded benchmark")
    parser.add_argument(
        "--benchmark", default="v1", choices=sorted(BENCHMARKS), help="the benchmark version run (default: v1)"
    )
    parser.add_argument(
        "--episodes",
        default=None,
        help="a number (with the benchmark's --scenes and --seed: its first N), or a file (default: the benchmark's)",
    )
    parser.add_argument("--seed", type=int, default=None, help="default: the benchmark's")
    parser.add_argument("--out", required=True, type=path, help="output directory (rerun to resume)")
    parser.add_argument("--methods", default=",".join(ALL_METHODS), help="comma-separated agent names")
    parser.add_argument("--scenes", default=None, help="a --scenes SPEC (default: the benchmark's)")
    add_max_steps(parser)
    parser.add_argument("--pictures", type=int, default=2, help="episodes drawn for the report (0: none)")
    add_floor_reference(parser, "METHOD", "the method (one of --methods)")
    parser.add_argument(
        "--regimes",
        default=None,
        help="each method under each perception and reasoning regime (comma-separated, or all: paper, "
        "exact-detector, strong-detector, weak-detector, oracle-reasoner, exploration-bound; docs/regimes.md) into "
        "DIR/regimes/, one table in DIR/regimes.md",
    )
    add_execution_options(parser)
    add_model_options(parser)
    add_config_options(parser)
    parser.set_defaults(handler=_cmd_bench_ablations)
    add_world_options(parser)  # last: a plug-in world's options are checked against every other option


def _add_bench_grounder(sub: Commands) -> None:
    parser = sub.add_parser(
        "grounder",
        help="SAM3 / OWLv2 / Grounding DINO (+ a box segmenter) per 640x480 frame in process and served: latency, "
        "stage split, GPU memory (no weights needed)",
    )
    _add_bench_model(parser)
    parser.add_argument("--frames", type=int, default=10, help="timed frames, one at a time (default 10)")
    parser.add_argument("--batch", type=int, default=1, help="B > 1: also time a batched forward of B frames")
    parser.add_argument(
        "--clients", type=int, default=0, help="K > 0: also time the served path with K concurrent clients (loopback)"
    )
    parser.add_argument(
        "--phrases",
        type=int,
        default=1,
        help="P: with --clients, the clients look for P different objects, as an eval's workers do (1 to 16; "
        "default 1: all the same)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=_cmd_bench_grounder)


def _add_bench_eval_throughput(sub: Commands) -> None:
    parser = sub.add_parser(
        "eval-throughput",
        help="drivenav eval beside one served grounder (random weights): episodes an hour, frames a second, where a "
        "step's time goes (arguments after -- go to eval)",
    )
    _add_bench_model(parser)
    parser.add_argument("--batch", type=int, default=16, help="the server's batch (default 16)")
    parser.add_argument("--batch-ms", type=float, default=5.0, help="the server's batch wait (default 5 ms)")
    parser.add_argument("--copies", type=int, default=1, help="copies of the model the server runs (default 1)")
    parser.add_argument("--workers", type=int, default=2, help="eval workers (default 2)")
    parser.add_argument(
        "--forward-ms",
        type=float,
        default=0.0,
        help="serve no model: each batch's forward waits MS ms and computes nothing (a GPU's time as the host sees "
        f"it; up to {MAX_FORWARD_MS:g} ms), to measure serving and the workers without a GPU",
    )
    parser.add_argument(
        "--window",
        type=float,
        default=None,
        help="stop the eval S seconds after it starts, as Ctrl-C does (its finished episodes kept): the figures of "
        "what ran, the served model's steady rate over nearly all of it (default: the eval runs to its end)",
    )
    parser.add_argument("--out", type=path, default=None, help="the eval's run directory (default: a temporary one)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "eval_args",
        nargs=argparse.REMAINDER,
        help=f"after --: the eval's episodes and agent (default: {' '.join(THROUGHPUT_EVAL)})",
    )
    parser.set_defaults(handler=_cmd_bench_eval_throughput)


MAX_WINDOW_S = 86_400.0
"""``bench eval-throughput --window``'s largest window: a day."""
THROUGHPUT_EVAL = ("--agent", "drive-nav", "--scenes", "procedural:4", "--episodes", "8", "--seed", "2026")
"""``bench eval-throughput``'s eval without arguments of its own: eight episodes in four procedural houses."""
MAX_FORWARD_MS = 10_000.0
"""``bench eval-throughput --forward-ms``'s largest wait a batch."""
THROUGHPUT_OWN = ("--out", "--workers", "--detector-shadow-url", "--detector", "--detector-url")
"""The eval options ``bench eval-throughput`` sets itself."""


def _add_bench_model(parser: argparse.ArgumentParser) -> None:
    """The model options of ``bench grounder`` and ``bench eval-throughput``."""
    from drivenav.semantics.model_spec import DTYPES
    from drivenav.semantics.registry import MODEL_DETECTORS

    parser.add_argument("--detector", choices=MODEL_DETECTORS, default="sam3")
    parser.add_argument(
        "--detector-model", default="", help="checkpoint dir or HF-cache model id (default: the detector's, if cached)"
    )
    add_segmenter_options(parser, own_defaults=True)
    parser.add_argument(
        "--random-weights", action="store_true", help="the full-size architectures with random weights, even if cached"
    )
    parser.add_argument("--tiny", action="store_true", help="the tests' tiny random models (a smoke test of the bench)")
    parser.add_argument("--device", default=None, help="cpu or cuda (default: cuda when visible)")
    parser.add_argument("--dtype", choices=DTYPES, default="auto", help="default auto: bf16 on CUDA, else fp32")
    parser.add_argument(
        "--compile", action="store_true", help="torch.compile the per-frame modules (compiled in the untimed frames)"
    )


def add_benchmark(commands: Commands) -> None:
    from drivenav.benchmarks.benchmark import BENCHMARKS

    parser = commands.add_parser("benchmark", help="the fixed, versioned embedded benchmark")
    sub = parser.add_subparsers(dest="benchmark_command", required=True)
    generate = sub.add_parser("generate", help="write a benchmark version's episodes (json.gz, same bytes each time)")
    generate.add_argument("--version", default="v1", choices=sorted(BENCHMARKS))
    generate.add_argument("--out", type=path, required=True)
    generate.add_argument("--episodes", type=int, default=None, help="only the first N episodes (quick checks)")
    generate.set_defaults(handler=_cmd_benchmark_generate)


def _cmd_bench_sim(args: argparse.Namespace) -> int:
    from drivenav.envs.embedded.bench import bench_sim
    from drivenav.envs.embedded.library import SceneLibrary

    scene = None
    if args.scene is not None:
        library = SceneLibrary("procedural,homes,storeys")
        if args.scene not in library:
            expected = "a generated scene id: procedural/house_N, homes/home_N or storeys/home_N"
            raise InputError("command line", "--scene", expected, args.scene)
        scene = library.load(args.scene)
    return print_bench(bench_sim(frames=positive(args.frames, "--frames"), scene=scene), args.json)


def _cmd_bench_directions(args: argparse.Namespace) -> int:
    from drivenav.directions.bench import bench_directions

    return print_bench(bench_directions(positive(args.repeats, "--repeats")), args.json)


def _cmd_bench_mapping(args: argparse.Namespace) -> int:
    from drivenav.mapping.bench import bench_mapping

    return print_bench(dict(bench_mapping(frames=positive(args.frames, "--frames"))), args.json)


def _cmd_bench_agent(args: argparse.Namespace) -> int:
    from drivenav.benchmarks.agent_bench import bench_agent

    result = bench_agent(
        positive(args.episodes, "--episodes"),
        positive(args.max_steps, "--max-steps"),
        agent_name=args.agent,
        benchmark=args.benchmark,
    )
    return print_bench(result, args.json)


def _cmd_bench_episodes(args: argparse.Namespace) -> int:
    from drivenav.benchmarks.episodes_bench import bench_episodes

    return print_bench(bench_episodes(episode_count(args.num, "--num")), args.json)


def _cmd_bench_robot(args: argparse.Namespace) -> int:
    from drivenav.brain.bench import bench_robot

    return print_bench(bench_robot(positive(args.repeats, "--repeats")), args.json)


def _bench_options(args: argparse.Namespace, **counts: int) -> GrounderBenchOptions:
    """The model options of ``bench grounder`` / ``bench eval-throughput`` (and the bench's ``counts``)."""
    from drivenav.semantics.grounder_bench import GrounderBenchOptions

    return GrounderBenchOptions(
        detector=args.detector,
        checkpoint=args.detector_model,
        segmenter=args.segmenter,
        segmenter_checkpoint=args.segmenter_model,
        random_weights=args.random_weights,
        tiny=args.tiny,
        device=args.device,
        dtype=args.dtype,
        compile=args.compile,
        **counts,
    )


@contextlib.contextmanager
def _models_extra(detector: str) -> Iterator[None]:
    """A missing torch / transformers / torchvision (the models extra) as one line."""
    try:
        yield
    except ImportError as error:
        extra = f"the models extra for {detector} (pip install 'drivenav[models]')"
        raise InputError("command line", "--detector", extra, str(error).splitlines()[0]) from None


def _cmd_bench_grounder(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from drivenav.semantics.grounder_bench import bench_grounder

    options = _bench_options(
        args,
        frames=positive(args.frames, "--frames"),
        batch=positive(args.batch, "--batch"),
        clients=positive(args.clients, "--clients") if args.clients else 0,
        phrases=args.phrases,
    )
    with _models_extra(args.detector):
        result = bench_grounder(options)
    return print_bench(asdict(result), args.json)


def _cmd_bench_eval_throughput(args: argparse.Namespace) -> int:
    """``bench eval-throughput``: the model served from this process, the eval run in it (its workers spawned)
    with the model as its detector's shadow (drivenav.benchmarks.throughput_bench)."""
    import tempfile
    from dataclasses import asdict

    from drivenav.benchmarks.throughput_bench import INTERRUPTED, served_eval
    from drivenav.cli.serve import serve_config

    eval_args = _throughput_eval_args(args.eval_args)
    forward_ms = _forward_ms(args)
    config = serve_config(args.batch, args.batch_ms, args.copies)
    options = _bench_options(args)
    workers = positive(args.workers, "--workers")
    with _models_extra(args.detector), tempfile.TemporaryDirectory(prefix="drivenav-throughput-") as scratch:
        out = args.out or Path(scratch) / "run"

        def run_eval(endpoint: str, run_dir: Path) -> int:
            from drivenav.cli import main

            own = ["--workers", str(workers), "--detector-shadow-url", endpoint, "--out", str(run_dir)]
            return main(["eval", *eval_args, *own])

        result = served_eval(options, config, workers, out, run_eval, forward_ms, _window(args))
        status = print_bench(asdict(result), args.json)
        return INTERRUPTED if result.stopped == "signal" else status


def _window(args: argparse.Namespace) -> float | None:
    """``--window``: seconds > 0, or None (the eval runs to its end)."""
    window: float | None = args.window
    if window is not None and not (0.0 < window <= MAX_WINDOW_S):
        raise InputError("command line", "--window", f"seconds in (0, {MAX_WINDOW_S:g}]", window)
    return window


def _forward_ms(args: argparse.Namespace) -> float:
    """``--forward-ms``: 0 (the model), or a wait a batch in (0, :data:`MAX_FORWARD_MS`] with no model option."""
    forward_ms: float = args.forward_ms
    if not (0.0 <= forward_ms <= MAX_FORWARD_MS):
        expected = f"0 (the model) or the milliseconds a batch's forward waits, at most {MAX_FORWARD_MS:g}"
        raise InputError("command line", "--forward-ms", expected, forward_ms)
    from drivenav.cli.serve import first_model_option

    option = first_model_option(args) if forward_ms > 0.0 else None
    if option is not None:
        raise InputError("command line", option, "no model option with --forward-ms (it serves no model)", option)
    return forward_ms


def _throughput_eval_args(given: list[str]) -> list[str]:
    """The eval's own arguments (after ``--``; :data:`THROUGHPUT_EVAL` without any); one the bench sets itself is
    refused in one line."""
    args = given[1:] if given[:1] == ["--"] else given
    for arg in args:
        if arg.split("=", 1)[0] in THROUGHPUT_OWN:
            expected = f"eval options other than {', '.join(THROUGHPUT_OWN)} (the bench sets them)"
            raise InputError("command line", "eval-throughput -- ...", expected, arg)
    return args or list(THROUGHPUT_EVAL)


def _cmd_bench_ablations(args: argparse.Namespace) -> int:
    """``bench ablations``: every method on the same episodes (``--benchmark``'s frozen ones by default), then the
    report's tables; the pictures are drawn by the viz floor's picture-maker, passed in."""
    from drivenav.analysis.ablations import RUNS_DIR, parse_methods, run_ablations
    from drivenav.eval.report import shown
    from drivenav.report.site import write_report
    from drivenav.viz.run_pictures import render_pictures

    methods = parse_methods(args.methods)
    if args.regimes is not None:
        return _bench_regimes(args, methods)
    reference = floor_reference(args, methods, "one of the --methods")
    pool = executor(args)
    if args.pictures < 0:
        raise InputError("command line", "--pictures", "a number of episodes >= 0", args.pictures)
    definition = _benchmark_options(args)
    specs = [run_spec(args, method) for method in methods]
    run_episodes = _benchmark_episodes(args, definition) if chosen_world(args).embedded_episodes else None
    report = run_ablations(
        run_episodes or episodes(args, specs[0]), specs, args.out, pool, args.pictures, render_pictures, reference
    )
    for name, entry in report.methods.items():
        sr, spl = (shown(value, "{:5.1f} %", 100.0) for value in (entry.success_rate, entry.spl))
        print(f"{name:<20} SR {sr}  SPL {spl}  errors {entry.errors}")
    print(f"tables: {args.out / 'ablations.md'}  data: {args.out / 'ablations.json'}, {args.out / 'ablations.csv'}")
    print(f"report: {write_report([args.out / RUNS_DIR / m for m in methods], args.out / 'report')}")
    return 0


def _bench_regimes(args: argparse.Namespace, methods: list[str]) -> int:
    """``bench ablations --regimes``: every method under every regime on the same episodes, then one table
    (:mod:`drivenav.analysis.regimes`)."""
    from drivenav.analysis.regimes import (
        build_regime_report,
        parse_regimes,
        regime_args,
        run_regimes,
        write_regime_report,
    )
    from drivenav.eval.report import shown

    regimes = parse_regimes(args.regimes)
    pool = executor(args)
    definition = _benchmark_options(args)
    specs = {r: [run_spec(regime_args(args, r), method) for method in methods] for r in regimes}
    first = specs[regimes[0]][0]
    run_episodes = _benchmark_episodes(args, definition) if chosen_world(args).embedded_episodes else None
    chosen = run_episodes or episodes(args, first)
    dirs = run_regimes(chosen, specs, args.out, pool)
    episode_set = f"benchmark {args.benchmark}, --episodes {args.episodes}, seed {args.seed}, scenes {args.scenes}"
    report = build_regime_report(dirs, len(chosen), episode_set)
    for regime, by in report.cells.items():
        for name, cell in by.items():
            sr, spl = (shown(value, "{:5.1f} %", 100.0) for value in (cell.entry.success_rate, cell.entry.spl))
            print(f"{regime:<18} {name:<20} SR {sr}  SPL {spl}  errors {cell.entry.errors}")
    write_regime_report(report, args.out)
    print(f"table: {args.out / 'regimes.md'}  data: {args.out / 'regimes.json'}, {args.out / 'regimes.csv'}")
    return 0


def _benchmark_options(args: argparse.Namespace) -> BenchmarkDefinition:
    """``--benchmark``'s definition; ``--episodes``, ``--seed`` and ``--scenes`` not given take its values."""
    from drivenav.benchmarks.benchmark import BENCHMARKS

    definition = BENCHMARKS[args.benchmark]
    args.episodes = str(definition.episodes) if args.episodes is None else args.episodes
    args.seed = definition.seed if args.seed is None else args.seed
    args.scenes = definition.scenes if args.scenes is None else args.scenes
    return definition


def _benchmark_episodes(args: argparse.Namespace, definition: BenchmarkDefinition) -> list[Episode] | None:
    """A number of episodes: the benchmark's first N (its frozen ones) with its own scenes and seed, else its
    generator's on the scenes and seed given; v1's generator on other scenes is the world's own (None: the
    world generates them). A file: None (the world reads it)."""
    from drivenav.benchmarks.benchmark import BenchmarkDefinition, generate_benchmark

    if not is_count(args.episodes):
        return None
    count = positive(int(args.episodes), "--episodes")
    if (args.scenes, args.seed) == (definition.scenes, definition.seed):
        return generate_benchmark(definition, count)
    if definition.generator == "uniform":
        return None
    return generate_benchmark(BenchmarkDefinition(args.scenes, count, args.seed, generator=definition.generator))


def _cmd_benchmark_generate(args: argparse.Namespace) -> int:
    from drivenav.benchmarks.benchmark import BENCHMARKS, generate_benchmark
    from drivenav.eval.episodes import save_episodes

    count = None if args.episodes is None else positive(args.episodes, "--episodes")
    written = generate_benchmark(BENCHMARKS[args.version], count)
    save_episodes(written, args.out)
    scenes = len({e.scene_id for e in written})
    print(f"benchmark {args.version}: {len(written)} episodes over {scenes} scenes written to {args.out}")
    return 0


RESUMABLE = (_cmd_bench_ablations,)
"""The handlers that write run directories episode by episode (rerun to resume)."""
