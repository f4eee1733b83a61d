"""A robot as a run sees it (``--env robot``, docs/robot.md): the endpoint and CURVE keys of ``--robot`` and
``--robot-keys``, the robot greeted once before any work, its episodes from a file."""

from __future__ import annotations

import argparse
import importlib.util
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.eval.options import is_count, path
from drivenav.worlds.entry import WorldEntry

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec
    from drivenav.episode import Episode
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings


def add_robot_address(group: argparse._ArgumentGroup) -> None:
    """``--robot`` and ``--robot-keys`` (also the options of ``drivenav run``)."""
    group.add_argument("--robot", default=None, metavar="ADDR", help="robot: its endpoint, e.g. tcp://10.0.0.2:5555")
    group.add_argument(
        "--robot-keys", type=path, default=None, metavar="DIR", help="robot: the brain's CURVE keys (robot keys DIR)"
    )


def _spec_class() -> type[EnvSpec]:
    from drivenav.envs.robot import RobotSpec

    return RobotSpec


def _build(args: argparse.Namespace, settings: Settings) -> EnvSpec:
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


def _episodes(args: argparse.Namespace, run: RunSpec) -> list[Episode]:
    """The robot's own episodes: a file (a robot generates none)."""
    from drivenav.eval.episodes import load_episodes

    if is_count(args.episodes):
        raise InputError("command line", "--episodes", "an episodes file with --env robot (the robot's)", args.episodes)
    return load_episodes(args.episodes)


ROBOT = WorldEntry(
    name="robot",
    summary="a robot",
    spec_class=_spec_class,
    build=_build,
    episodes=_episodes,
    label=lambda args: f"the robot at {args.robot}",
    add_options=add_robot_address,
    own_options=("--robot",),
    docs="docs/robot.md",
    embedded_episodes=True,  # serve-sim serves the embedded world's episodes
)
