"""The ``drivenav`` command line: evaluation, episode generation, benchmarks, pictures and the demo.

Bad input (files, fields, options) prints one line naming what was wrong and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import math
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drivenav.errors import InputError, RunStoppedError, WorkerDiedError
from drivenav.threads import limit_blas_threads

if TYPE_CHECKING:
    from drivenav.envs.episode import Episode
    from drivenav.envs.habitat.spec import HabitatSpec
    from drivenav.envs.robot import RobotSpec
    from drivenav.eval.executor import Executor
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings

limit_blas_threads()  # before numpy loads

Handler = Callable[[argparse.Namespace], int]


def _add_eval(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.methods import agent_names

    parser = commands.add_parser("eval", help="run an agent on episodes and write metrics")
    parser.add_argument("--agent", required=True, help=f"agent name ({', '.join(agent_names())})")
    parser.add_argument("--scenes", default="procedural", help="procedural[:K], a scene dir, or a folder of them")
    parser.add_argument(
        "--episodes",
        required=True,
        help="embedded: a number of episodes to generate, or an episodes file; habitat: N (the split's first) or all",
    )
    _add_world_options(parser)
    _add_run_seed(parser)
    parser.add_argument("--out", required=True, type=_path, help="run directory (rerun to resume)")
    _add_max_steps(parser)
    _add_execution_options(parser)
    _add_model_options(parser)
    _add_config_options(parser)
    parser.set_defaults(handler=_cmd_eval)


def _add_max_steps(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--max-steps", type=int, default=None, help="step budget (default 500; sets sim.max_steps)")


def _add_run_seed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=None, help="run seed (default 0; sets run.seed)")


def _add_run(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("run", help="one live episode on a robot (docs/robot.md)")
    parser.add_argument("--env", default="robot", choices=("robot",), help="the world: a robot")
    parser.add_argument("--target", required=True, help='what to find, e.g. "fire extinguisher"')
    parser.add_argument("--agent", default="drive-nav", help="agent name (default drive-nav)")
    parser.add_argument("--out", type=_path, default=None, help="run directory (default runs/live-DATE-TIME)")
    parser.add_argument(
        "--episode-id", default=None, help="the episode id sent with RESET (serve-sim: one of its episodes)"
    )
    _add_max_steps(parser)
    _add_run_seed(parser)
    group = parser.add_argument_group("robot")
    _add_robot_address(group)
    _add_model_options(parser)
    _add_config_options(parser)
    parser.set_defaults(handler=_cmd_run)


def _add_robot(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("robot", help="the robot side: keys, serve a robot, serve the embedded world")
    sub = parser.add_subparsers(dest="robot_command", required=True)
    keys = sub.add_parser("keys", help="write CURVE key pairs and the allow-list (DIR/server.key, DIR/client.key, ...)")
    keys.add_argument("dir", type=_path)
    keys.set_defaults(handler=_cmd_robot_keys)
    serve = sub.add_parser("serve", help="serve this robot's sensors and motion (ROS 2 topics or a ROS 2 bag)")
    serve.add_argument("--bind", default="tcp://127.0.0.1:5555", help="endpoint (default tcp://127.0.0.1:5555)")
    serve.add_argument("--keys", type=_path, default=None, help="CURVE keys (required off loopback)")
    serve.add_argument("--source", default="ros2", choices=("ros2", "bag"), help="ROS 2 topics or a bag")
    serve.add_argument("--bag", type=_path, default=None, help="with --source bag: the ROS 2 bag folder")
    serve.add_argument("--motion", default="cmd-vel", choices=("cmd-vel", "none"), help="cmd_vel on odometry, or none")
    serve.add_argument("--lidar", action="store_true", help="send LiDAR occupancy in the camera's field of view")
    serve.add_argument("--jpeg", action="store_true", help="RGB as JPEG (default raw)")
    _add_config_options(serve)
    serve.set_defaults(handler=_cmd_robot_serve)
    sim = sub.add_parser("serve-sim", help="the embedded world served as a robot, with metrics per episode")
    sim.add_argument("--scenes", default="procedural", help="a --scenes SPEC")
    sim.add_argument("--episodes", required=True, type=_path, help="the episodes file the brain will run")
    sim.add_argument("--bind", default="tcp://127.0.0.1:5555", help="endpoint (default tcp://127.0.0.1:5555)")
    sim.add_argument("--keys", type=_path, default=None, help="CURVE keys (required off loopback)")
    sim.add_argument("--seed", type=int, default=0, help="the scenes' seed (procedural scenes)")
    sim.add_argument("--lidar", action="store_true", help="simulate a 2-D LiDAR and send its occupancy")
    _add_config_options(sim)
    sim.set_defaults(handler=_cmd_robot_serve_sim)


def _add_world_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.envs.habitat.benchmarks import BENCHMARKS

    group = parser.add_argument_group("world (--env habitat: see docs/habitat.md; --env robot: docs/robot.md)")
    group.add_argument("--env", default="embedded", choices=WORLDS, help="the embedded simulator, Habitat or a robot")
    group.add_argument(
        "--split", default=None, help="habitat: the benchmark split (--config names the benchmark: hm3d-ovon, ...)"
    )
    group.add_argument("--data-dir", type=_path, default=None, help="habitat: habitat's data/ folder")
    group.add_argument(
        "--habitat-plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="habitat: a module to import in every worker (custom simulator, sensors, datasets); repeatable",
    )
    group.set_defaults(benchmarks=sorted(BENCHMARKS))
    _add_robot_address(group)


def _add_robot_address(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--robot", default=None, metavar="ADDR", help="robot: its endpoint, e.g. tcp://10.0.0.2:5555")
    group.add_argument(
        "--robot-keys", type=_path, default=None, metavar="DIR", help="robot: the brain's CURVE keys (robot keys DIR)"
    )


WORLDS = ("embedded", "habitat", "robot")
HABITAT_PREFIX = "habitat."  # --set habitat.KEY=VALUE: a habitat-lab override, passed through as KEY=VALUE


def _add_config_options(parser: argparse.ArgumentParser) -> None:
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


_OPTION_KEYS = {
    "seed": "run.seed",
    "max_steps": "sim.max_steps",
    "reasoner": "models.reasoner",
    "detector": "models.detector",
    "vlm_base_url": "models.vlm_base_url",
    "vlm_model": "models.vlm_model",
    "vlm_record": "models.vlm_record",
    "vlm_replay": "models.vlm_replay",
    "detector_model": "models.detector_model",
}


def _settings(args: argparse.Namespace, agent: str | None) -> Settings:
    """The resolved configuration: defaults, ``agent``'s preset, ``--config``, the options given, ``--set``."""
    from drivenav.settings import load_settings

    given = _given_options(args)
    for key in ("models.vlm_record", "models.vlm_replay"):
        if given.get(key):
            given[key] = str(Path(str(given[key])).resolve())
    if "run.seed" in given:
        _seed(int(str(given["run.seed"])))
    benchmark = _benchmark_presets(args)
    configs = [*benchmark, *(c for c in args.config if c not in benchmark)]
    overrides = [o for o in args.overrides if not o.startswith(HABITAT_PREFIX)]
    return load_settings(agent, configs=configs, overrides=overrides, options=given)


def _given_options(args: argparse.Namespace) -> dict[str, object]:
    """The dedicated options given on the command line, as settings keys (``--seed`` -> ``run.seed``, ...)."""
    return {key: getattr(args, name) for name, key in _OPTION_KEYS.items() if getattr(args, name, None) is not None}


def _is_habitat(args: argparse.Namespace) -> bool:
    return getattr(args, "env", "embedded") == "habitat"


def _benchmark_presets(args: argparse.Namespace) -> list[str]:
    """The ``--config`` benchmark of a Habitat run (first: its settings preset, e.g. the success distance, lies
    under every other layer)."""
    return [_benchmark(args)] if _is_habitat(args) else []


def _benchmark(args: argparse.Namespace) -> str:
    named = [c for c in args.config if c in args.benchmarks]
    if len(named) != 1:
        expected = f"exactly one Habitat benchmark with --env habitat ({', '.join(args.benchmarks)})"
        raise InputError("command line", "--config", expected, ", ".join(named or args.config) or "none")
    return str(named[0])


def _habitat_overrides(args: argparse.Namespace) -> tuple[str, ...]:
    """``--set habitat.KEY=VALUE``: habitat-lab's own keys (they start with ``habitat.``), only with --env habitat."""
    found = tuple(o for o in args.overrides if o.startswith(HABITAT_PREFIX))
    if found and not _is_habitat(args):
        raise InputError("command line", "--set", "habitat.KEY=VALUE only with --env habitat", found[0])
    return found


def _add_execution_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.eval.executor import EXECUTORS

    parser.add_argument(
        "--workers", type=int, default=None, help="parallel workers (default: 1 local, every CPU of a Ray cluster)"
    )
    parser.add_argument("--executor", default="local", choices=EXECUTORS, help="local processes or Ray tasks")
    parser.add_argument("--ray-address", default=None, help="a Ray cluster (default: a private local instance)")


def _executor(args: argparse.Namespace) -> Executor:
    from drivenav.eval.executor import Executor

    return Executor(args.executor, args.workers, args.ray_address)


def _add_model_options(parser: argparse.ArgumentParser) -> None:
    from drivenav.semantics.registry import DETECTORS, REASONERS, ModelSpec

    default = ModelSpec()
    models = parser.add_argument_group("models (reasoner = the VLM's role, detector = SAM3's role; sets models.*)")
    models.add_argument("--reasoner", help=f"one of {', '.join(REASONERS)} (default {default.reasoner})")
    models.add_argument("--detector", help=f"one of {', '.join(DETECTORS)} (default {default.detector})")
    models.add_argument("--vlm-base-url", help=f"OpenAI-compatible endpoint (default {default.vlm_base_url})")
    models.add_argument("--vlm-model", help=f"default {default.vlm_model}")
    models.add_argument("--vlm-record", help="record every reasoner request/answer to this file")
    models.add_argument("--vlm-replay", help="with --reasoner replay: answer from this recording")
    models.add_argument("--detector-model", help="local checkpoint dir or HF-cache model id")


def _add_episodes(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.envs.habitat.benchmarks import LAYOUTS

    parser = commands.add_parser("episodes", help="episode files")
    sub = parser.add_subparsers(dest="episodes_command", required=True)
    generate = sub.add_parser("generate", help="generate HM3D-OVON-style episodes (json.gz)")
    generate.add_argument("--scenes", default="procedural")
    generate.add_argument("--num", type=int, required=True)
    generate.add_argument("--seed", type=int, default=0)
    generate.add_argument("--out", type=_path, required=True)
    generate.set_defaults(handler=_cmd_episodes_generate)
    export = sub.add_parser("export", help="write an episodes file in a Habitat layout (ObjectNav v1 or HM3D-OVON)")
    export.add_argument("--episodes", required=True, type=_path, help="an episodes file (drivenav's json.gz)")
    export.add_argument("--format", required=True, choices=LAYOUTS, help="the Habitat dataset layout")
    export.add_argument("--split", default="val", help="the split's name (default val)")
    export.add_argument("--out", required=True, type=_path, help="the dataset folder: writes OUT/SPLIT/SPLIT.json.gz")
    export.set_defaults(handler=_cmd_episodes_export)


def _add_doctor(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.envs.habitat.benchmarks import BENCHMARKS

    parser = commands.add_parser("doctor", help="check a Habitat / VLM / segmenter set-up before a long run")
    parser.add_argument("--env", default="embedded", choices=WORLDS)
    parser.add_argument("--config", default=None, choices=sorted(BENCHMARKS), help="with --env habitat: benchmark")
    parser.add_argument("--split", default=None, help="one split (default: every split of the benchmark)")
    parser.add_argument("--data-dir", type=_path, default=None, help="habitat's data/ folder")
    _add_model_options(parser)
    parser.set_defaults(handler=_cmd_doctor)


def _add_bench(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("bench", help="speed benchmarks")
    sub = parser.add_subparsers(dest="bench_command", required=True)
    sim = sub.add_parser("sim", help="embedded simulator frames per second (RGB + depth + semantic, one core)")
    sim.add_argument("--frames", type=int, default=300)
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
    agent.add_argument("--json", action="store_true", help="print one JSON object")
    agent.set_defaults(handler=_cmd_bench_agent)
    _add_bench_ablations(sub)
    episodes = sub.add_parser("episodes", help="a large episodes file: read, check, digest, copy, memory per episode")
    episodes.add_argument("--num", type=int, default=100_000)
    episodes.add_argument("--json", action="store_true", help="print one JSON object")
    episodes.set_defaults(handler=_cmd_bench_episodes)
    robot = sub.add_parser("robot", help="robot protocol round trip of one 640x480 observation, plain and CURVE")
    robot.add_argument("--repeats", type=int, default=200)
    robot.add_argument("--json", action="store_true", help="print one JSON object")
    robot.set_defaults(handler=_cmd_bench_robot)


def _add_bench_ablations(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.eval.benchmark import BENCHMARK_V1
    from drivenav.methods import ALL_METHODS

    parser = sub.add_parser("ablations", help="the paper's Tables II, V, VI and VII on the embedded benchmark")
    parser.add_argument(
        "--episodes",
        default=str(BENCHMARK_V1.episodes),
        help="a number (with the default --scenes and --seed: the first N of benchmark v1), or a file",
    )
    parser.add_argument("--seed", type=int, default=BENCHMARK_V1.seed)
    parser.add_argument("--out", required=True, type=_path, help="output directory (rerun to resume)")
    parser.add_argument("--methods", default=",".join(ALL_METHODS), help="comma-separated agent names")
    parser.add_argument("--scenes", default=BENCHMARK_V1.scenes, help="a --scenes SPEC (default: benchmark v1's)")
    _add_max_steps(parser)
    parser.add_argument("--pictures", type=int, default=2, help="episodes drawn for the report (0: none)")
    _add_world_options(parser)
    _add_execution_options(parser)
    _add_model_options(parser)
    _add_config_options(parser)
    parser.set_defaults(handler=_cmd_bench_ablations)


def _add_benchmark(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.eval.benchmark import BENCHMARKS

    parser = commands.add_parser("benchmark", help="the fixed, versioned embedded benchmark")
    sub = parser.add_subparsers(dest="benchmark_command", required=True)
    generate = sub.add_parser("generate", help="write a benchmark version's episodes (json.gz, same bytes each time)")
    generate.add_argument("--version", default="v1", choices=sorted(BENCHMARKS))
    generate.add_argument("--out", type=_path, required=True)
    generate.add_argument("--episodes", type=int, default=None, help="only the first N episodes (quick checks)")
    generate.set_defaults(handler=_cmd_benchmark_generate)


def _add_viz(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("viz", help="pictures of a finished episode")
    parser.add_argument("run_dir", type=_path)
    parser.add_argument("episode_id")
    parser.add_argument("--out", type=_path, default=None, help="output folder (default RUN_DIR/viz)")
    parser.add_argument("--rerun", action="store_true", help="also a Rerun recording (.rrd) of the same streams")
    parser.set_defaults(handler=_cmd_viz)


def _add_compare(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("compare", help="compare runs; steps and revisits on commonly solved long episodes")
    parser.add_argument("run_dirs", type=_path, nargs="+")
    parser.add_argument("--min-distance", type=float, default=10.0, help="Table II: geodesic distance above this")
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(handler=_cmd_compare)


def _add_demo(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser("demo", help="a short embedded benchmark with pictures")
    parser.add_argument("--out", type=_path, default=Path("demo-output"))
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    parser.set_defaults(handler=_cmd_demo)


def _add_config(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from drivenav.methods import agent_names

    parser = commands.add_parser("config", help="the configuration tree")
    sub = parser.add_subparsers(dest="config_command", required=True)
    show = sub.add_parser("show", help="print the resolved configuration as YAML (loads back with --config)")
    show.add_argument("--agent", default=None, help=f"apply this method's preset ({', '.join(agent_names())})")
    _add_config_options(show)
    show.set_defaults(handler=_cmd_config_show)


def _cmd_config_show(args: argparse.Namespace) -> int:
    from drivenav.settings import settings_to_yaml

    print(settings_to_yaml(_settings(args, args.agent)), end="")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="drivenav", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true")
    commands = parser.add_subparsers(dest="command", required=True)
    adders = (_add_eval, _add_run, _add_config, _add_episodes, _add_benchmark, _add_bench, _add_viz, _add_compare)
    for add in (*adders, _add_demo, _add_robot, _add_doctor):
        add(commands)
    return parser


def _path(text: str) -> Path:
    """A path option's value; an empty one (which would mean the current folder) is refused."""
    if not text:
        raise argparse.ArgumentTypeError("expected a path, got an empty string")
    return Path(text)


def _positive(value: int, option: str) -> int:
    if value < 1:
        raise InputError("command line", option, "a positive integer", value)
    return value


MAX_EPISODES = 1_000_000  # more episodes than any benchmark split: a typo, not a run


def _episode_count(value: int, option: str) -> int:
    count = _positive(value, option)
    if count > MAX_EPISODES:
        raise InputError("command line", option, f"a number of episodes up to {MAX_EPISODES:,}", count)
    return count


def _seed(value: int) -> int:
    if value < 0:
        raise InputError("command line", "--seed", "an integer >= 0", value)
    return value


def _load_or_generate(args: argparse.Namespace, settings: Settings) -> list[Episode]:
    """The run's episodes: ``--episodes N`` generated with the run seed, or an episodes file checked against the
    scenes."""
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import generate_episodes, load_episodes, validate_for_scenes

    seed = settings.run.seed
    library = SceneLibrary(args.scenes, seed)
    if str(args.episodes).isdigit():
        count = _episode_count(int(args.episodes), "--episodes")
        return generate_episodes(library, count, seed, settings.sim)
    episodes = load_episodes(args.episodes)
    validate_for_scenes(episodes, library, args.episodes, settings.sim)
    return episodes


def _run_spec(args: argparse.Namespace, agent: str) -> RunSpec:
    """The world (``--env``) and the resolved settings for ``agent``; models are checked before any work."""
    from drivenav.envs.embedded.env import EmbeddedSpec
    from drivenav.eval.runner import RunSpec
    from drivenav.semantics.registry import check_models

    _check_world_options(args)
    habitat = _habitat_overrides(args)
    settings = _settings(args, agent)
    check_models(settings.models)
    if _is_robot(args):
        return RunSpec(_robot_spec(args, settings), settings)
    if not _is_habitat(args):
        return RunSpec(EmbeddedSpec(args.scenes, settings.run.seed), settings)
    return RunSpec(_habitat_spec(args, settings, habitat), settings)


def _check_world_options(args: argparse.Namespace) -> None:
    """A world's own options only with that world (before any model loads)."""
    if getattr(args, "robot", None) and not _is_robot(args):
        raise InputError("command line", "--robot", "only with --env robot", args.robot)
    for option, value in (("--split", getattr(args, "split", None)), ("--data-dir", getattr(args, "data_dir", None))):
        if value is not None and not _is_habitat(args):
            raise InputError("command line", option, "only with --env habitat", str(value))


def _is_robot(args: argparse.Namespace) -> bool:
    return getattr(args, "env", "embedded") == "robot"


def _robot_spec(args: argparse.Namespace, settings: Settings) -> RobotSpec:
    """The robot at ``--robot`` (CURVE with ``--robot-keys``), greeted once: its settings must match ``sim``, and
    it says what ground truth it provides (a simulated robot: instance labels)."""
    if importlib.util.find_spec("zmq") is None:
        raise InputError("command line", "--env", "pyzmq installed for --env robot: pip install 'drivenav[robot]'")
    from drivenav.envs.robot import RobotSpec, probe
    from drivenav.wire.security import check_endpoint

    if not args.robot:
        raise InputError("command line", "--robot", "the robot's endpoint with --env robot, e.g. tcp://HOST:5555")
    check_endpoint(args.robot, "--robot")
    if getattr(args, "workers", None) not in (None, 1):
        raise InputError("command line", "--workers", "1 with --env robot (one robot runs one episode at a time)")
    keys = "" if args.robot_keys is None else str(args.robot_keys.resolve())
    spec = RobotSpec(args.robot, keys)
    info = probe(spec, settings.sim)
    return RobotSpec(args.robot, keys, info.provides)


def _habitat_spec(args: argparse.Namespace, settings: Settings, overrides: tuple[str, ...]) -> HabitatSpec:
    """The Habitat world of ``--config BENCHMARK --split --data-dir``; a semantic sensor where the agent's models
    need ground-truth labels."""
    from drivenav.agent.registry import make_agent
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
    semantic = SEMANTIC in make_agent(settings).requires
    data_dir = str(args.data_dir.resolve())
    spec = HabitatSpec(_benchmark(args), args.split, data_dir, overrides, semantic, tuple(args.habitat_plugin))
    check_habitat_config(spec, settings.sim)
    return spec


def _episodes(args: argparse.Namespace, spec: RunSpec) -> list[Episode]:
    """The run's episodes: the embedded world's (:func:`_load_or_generate`), or a Habitat split's first N / all."""
    from drivenav.envs.habitat.spec import HabitatSpec
    from drivenav.eval.episodes import load_episodes

    if spec.env.name == "robot":  # the robot's own episodes (pyzmq is imported only for robot runs)
        if str(args.episodes).isdigit():
            raise InputError(
                "command line", "--episodes", "an episodes file with --env robot (the robot's)", args.episodes
            )
        return load_episodes(args.episodes)
    if not isinstance(spec.env, HabitatSpec):
        return _load_or_generate(args, spec.settings)
    episodes = spec.env.episodes()
    if str(args.episodes) == "all":
        return episodes
    if not str(args.episodes).isdigit():
        raise InputError("command line", "--episodes", "N (the split's first N episodes) or all", args.episodes)
    return episodes[: _positive(int(args.episodes), "--episodes")]


def _world_label(args: argparse.Namespace) -> str:
    if _is_robot(args):
        return f"the robot at {args.robot}"
    return f"{_benchmark(args)} {args.split}" if _is_habitat(args) else str(args.scenes)


def _cmd_eval(args: argparse.Namespace) -> int:
    from drivenav.eval.report import format_table
    from drivenav.eval.rundir import EPISODES_FILE, SUMMARY_FILE, make_directory
    from drivenav.eval.runner import evaluate

    executor = _executor(args)
    spec = _run_spec(args, args.agent)  # an unknown agent or setting fails before any work
    make_directory(args.out)
    episodes = _episodes(args, spec)
    summary = evaluate(episodes, spec, args.out, executor)
    print(format_table(summary, f"{args.agent} on {_world_label(args)}"))
    print(f"results: {args.out / EPISODES_FILE}  summary: {args.out / SUMMARY_FILE}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    import time

    from drivenav.brain.live import run_live

    if not args.target.strip():
        raise InputError("command line", "--target", "the object to find, e.g. 'fire extinguisher'", args.target)
    spec = _run_spec(args, args.agent)
    out = args.out or Path("runs") / time.strftime("live-%Y%m%d-%H%M%S")
    record, picture = run_live(spec, args.target, out, args.episode_id)
    print(f"{record.stop_reason} after {record.steps} steps{': ' + record.error if record.error else ''}")
    print(f"run: {out}  picture: {picture or 'none (the episode ended before it started)'}")
    return 1 if record.error else 0


def _cmd_robot_keys(args: argparse.Namespace) -> int:
    from drivenav.wire.security import write_keys

    for path in write_keys(args.dir):
        print(path)
    return 0


def _cmd_robot_serve(args: argparse.Namespace) -> int:
    from drivenav.robot.serve import robot_parts, serve_robot
    from drivenav.wire.security import check_bind

    check_bind(args.bind, args.keys)  # before any topic or file is opened
    sim = _settings(args, None).sim
    source, motion = robot_parts(args.source, args.bag, args.motion)
    serve_robot(args.bind, args.keys, source, motion, sim, args.lidar, args.jpeg)
    return 0


def _cmd_robot_serve_sim(args: argparse.Namespace) -> int:
    from drivenav.robot.serve import serve_simulation

    settings = _settings(args, None)
    serve_simulation(args.scenes, _seed(args.seed), args.episodes, args.bind, args.keys, args.lidar, settings.sim)
    return 0


def _cmd_bench_robot(args: argparse.Namespace) -> int:
    from drivenav.brain.bench import bench_robot

    return _print_bench(bench_robot(_positive(args.repeats, "--repeats")), args.json)


def _cmd_bench_episodes(args: argparse.Namespace) -> int:
    from drivenav.eval.episodes_bench import bench_episodes

    return _print_bench(bench_episodes(_episode_count(args.num, "--num")), args.json)


def _cmd_episodes_generate(args: argparse.Namespace) -> int:
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.episodes import generate_episodes, save_episodes
    from drivenav.types import SimConfig

    count = _episode_count(args.num, "--num")
    library = SceneLibrary(args.scenes, _seed(args.seed))
    episodes = generate_episodes(library, count, args.seed, SimConfig())
    save_episodes(episodes, args.out)
    synonyms = sum(bool(e.info.get("synonym")) for e in episodes)
    scenes = len({e.scene_id for e in episodes})
    print(f"wrote {len(episodes)} episodes over {scenes} scenes ({synonyms} by synonym) to {args.out}")
    return 0


def _cmd_episodes_export(args: argparse.Namespace) -> int:
    from drivenav.envs.habitat.layouts import write_split
    from drivenav.eval.episodes import load_episodes

    episodes = load_episodes(args.episodes)
    split = str(args.split)
    if not split or "/" in split or split.startswith("."):
        raise InputError("command line", "--split", "a split name such as val", split)
    written = write_split(episodes, args.out / split / f"{split}.json.gz", args.format)
    print(f"wrote {len(episodes)} episodes as {args.format} to {written[0]} and {len(written) - 1} content files")
    return 0


def _cmd_doctor(args: argparse.Namespace) -> int:
    from drivenav.doctor import DoctorRequest, format_checks, run_checks
    from drivenav.settings import load_settings

    models = load_settings(options=_given_options(args)).models
    if _is_habitat(args) and args.config is None:
        raise InputError("command line", "--config", "a Habitat benchmark with --env habitat", None)
    benchmark = str(args.config) if _is_habitat(args) else ""
    checks = run_checks(DoctorRequest(models, benchmark, args.data_dir, args.split))
    print(format_checks(checks))
    return 0 if all(check.ok for check in checks) else 1


def _print_bench(result: dict[str, Any], as_json: bool) -> int:
    if as_json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:>20}: {value}")
    return 0


def _cmd_bench_sim(args: argparse.Namespace) -> int:
    from drivenav.envs.embedded.bench import bench_sim

    return _print_bench(bench_sim(frames=_positive(args.frames, "--frames")), args.json)


def _cmd_bench_directions(args: argparse.Namespace) -> int:
    from drivenav.directions.bench import bench_directions

    return _print_bench(bench_directions(_positive(args.repeats, "--repeats")), args.json)


def _cmd_bench_mapping(args: argparse.Namespace) -> int:
    from drivenav.mapping.bench import bench_mapping

    return _print_bench(dict(bench_mapping(frames=_positive(args.frames, "--frames"))), args.json)


def _cmd_bench_agent(args: argparse.Namespace) -> int:
    from drivenav.eval.agent_bench import bench_agent

    result = bench_agent(_positive(args.episodes, "--episodes"), _positive(args.max_steps, "--max-steps"))
    return _print_bench(result, args.json)


def _cmd_bench_ablations(args: argparse.Namespace) -> int:
    from drivenav.eval.ablations import parse_methods, run_ablations
    from drivenav.eval.benchmark import BENCHMARK_V1, generate_benchmark
    from drivenav.eval.report import shown

    methods = parse_methods(args.methods)
    executor = _executor(args)
    if args.pictures < 0:
        raise InputError("command line", "--pictures", "a number of episodes >= 0", args.pictures)
    benchmark_v1 = (args.scenes, args.seed) == (BENCHMARK_V1.scenes, BENCHMARK_V1.seed) and not _is_habitat(args)
    specs = [_run_spec(args, method) for method in methods]
    if benchmark_v1 and str(args.episodes).isdigit():  # v1's frozen episodes, not today's generator's
        episodes = generate_benchmark(BENCHMARK_V1, _positive(int(args.episodes), "--episodes"))
    else:
        episodes = _episodes(args, specs[0])
    report = run_ablations(episodes, specs, args.out, executor, args.pictures)
    for name, entry in report["methods"].items():
        sr, spl = (shown(entry[key], "{:5.1f} %", 100.0) for key in ("success_rate", "spl"))
        print(f"{name:<20} SR {sr}  SPL {spl}  errors {entry['errors']}")
    print(f"tables: {args.out / 'ablations.md'}  data: {args.out / 'ablations.json'}, {args.out / 'ablations.csv'}")
    return 0


def _cmd_benchmark_generate(args: argparse.Namespace) -> int:
    from drivenav.eval.benchmark import BENCHMARKS, generate_benchmark
    from drivenav.eval.episodes import save_episodes

    count = None if args.episodes is None else _positive(args.episodes, "--episodes")
    episodes = generate_benchmark(BENCHMARKS[args.version], count)
    save_episodes(episodes, args.out)
    scenes = len({e.scene_id for e in episodes})
    print(f"benchmark {args.version}: {len(episodes)} episodes over {scenes} scenes written to {args.out}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from drivenav.eval.compare import compare, format_comparison

    if not (math.isfinite(args.min_distance) and args.min_distance >= 0.0):
        raise InputError("command line", "--min-distance", "a distance in metres >= 0", args.min_distance)
    dirs = {}
    for path in args.run_dirs:
        if not (path / "episodes.jsonl").is_file():
            raise InputError(path, "RUN_DIR", "a run directory written by 'drivenav eval'")
        dirs[path.name] = path
    result = compare(dirs, args.min_distance)
    if len(dirs) > 1 and result["shared_episodes"] == 0:
        raise InputError("command line", "RUN_DIR", "runs over the same episodes (these share none)")
    print(json.dumps(result) if args.json else format_comparison(result))
    return 0


def _cmd_viz(args: argparse.Namespace) -> int:
    from drivenav.viz.episode import render_episode_pictures

    paths = render_episode_pictures(args.run_dir, args.episode_id, args.out, rerun=args.rerun)
    for path in paths:
        print(path)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from drivenav.viz.demo import run_demo

    index = run_demo(args.out, _positive(args.episodes, "--episodes"), args.seed)
    print(f"demo results and pictures: {args.out.resolve()}  (start with {index})")
    return 0


def _interrupt_on_sigterm() -> None:
    """SIGTERM (a scheduler's or ``kill``'s stop) behaves like Ctrl-C: finished episodes stay saved."""

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    handler: Handler = args.handler
    _interrupt_on_sigterm()
    try:
        return handler(args)
    except InputError as error:
        print(f"drivenav: error: {error}", file=sys.stderr)
        return 2
    except (WorkerDiedError, RunStoppedError) as error:
        print(f"drivenav: error: {error}", file=sys.stderr)
        return 1
    except OSError as error:  # a path given that cannot be written or read (a folder, too long, under /proc)
        if error.filename is None:
            raise
        name = str(error.filename)
        shown = name if len(name) <= 200 else f"{name[:100]}...{name[-60:]} ({len(name)} characters)"
        print(f"drivenav: error: {shown}: {error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        serving = handler in (_cmd_robot_serve, _cmd_robot_serve_sim)
        said = "stopped serving (the robot is halted)" if serving else "finished episodes are saved; rerun to resume"
        print(f"drivenav: interrupted ({said})", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
