"""The robot's parts by command-line name: where ``drivenav robot serve`` reads its sensors (``--source``,
entry-point group ``drivenav.robot_sources``) and what carries out an action (``--motion``, group
``drivenav.robot_motions``); drivenav's own and other packages' (:mod:`drivenav.plugins`).

A part is registered by a :class:`SourceEntry` or a :class:`MotionEntry`: its name, a summary for ``--help``, the
options it adds to ``robot serve`` (refused when another part of its kind is chosen) and how it is built from the
parsed command line and the set-up the robot says it has (``sim``: the camera, the step length and turn angle).
Entries are light -- a part's own modules (``rclpy``, ``rosbags``) are imported when it is built -- so the command
line lists and offers them without loading numpy. A part that cannot be built (no ROS 2 sourced, a bag that does
not read) is one :class:`~drivenav.errors.InputError` line naming its option.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from drivenav.errors import InputError, one_line
from drivenav.eval.options import path
from drivenav.plugins import OptionAdder, Registry, add_options_of, no_options, refuse_options

if TYPE_CHECKING:
    from drivenav.robot.parts import MotionExecutor, SensorSource
    from drivenav.types import SimConfig

Part = TypeVar("Part")
T = TypeVar("T")


@dataclass(frozen=True)
class PartEntry(Generic[Part]):
    """One part of a robot by its command-line name.

    ``summary`` describes it in its option's help; ``add_options`` adds its own options to ``robot serve`` and
    ``own_options`` names them (refused when another part is chosen); ``build`` makes the part from the parsed
    command line and the robot's set-up (``sim``), raising :class:`~drivenav.errors.InputError` for an option that
    does not fit.
    """

    name: str
    summary: str
    build: Callable[[argparse.Namespace, SimConfig], Part]
    add_options: OptionAdder = no_options
    own_options: tuple[str, ...] = ()


Entry = TypeVar("Entry", bound=PartEntry[Any])


class SourceEntry(PartEntry["SensorSource"]):
    """A sensor source (:class:`~drivenav.robot.parts.SensorSource`) by ``--source`` name: the object an entry point
    of group ``drivenav.robot_sources`` names."""


class MotionEntry(PartEntry["MotionExecutor"]):
    """A motion executor (:class:`~drivenav.robot.parts.MotionExecutor`) by ``--motion`` name: the object an entry
    point of group ``drivenav.robot_motions`` names."""


# -- drivenav's own parts -----------------------------------------------------------------------------------------


def _ros2_source(args: argparse.Namespace, sim: SimConfig) -> SensorSource:
    from drivenav.robot import ros

    return _with_ros(ros.RosSensorSource, "--source", "ros2")


def _bag_options(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--bag", type=path, default=None, help="with --source bag: the ROS 2 bag folder")


def _bag_source(args: argparse.Namespace, sim: SimConfig) -> SensorSource:
    """The bag's sensor source; a folder rosbags cannot read (no or broken metadata, another storage) is one line."""
    from drivenav.robot import ros

    bag: Path | None = args.bag
    if bag is None or not bag.is_dir():
        raise InputError("command line", "--bag", "a ROS 2 bag folder with --source bag", bag)
    try:
        return ros.BagSource(bag, ros.RosTopics())
    except InputError:
        raise
    except Exception as error:  # rosbags' errors (AnyReaderError, FileNotFoundError, ...) share no base class
        raise InputError(bag, "--bag", "a ROS 2 bag folder rosbags can read", one_line(error)) from None


def _cmd_vel_motion(args: argparse.Namespace, sim: SimConfig) -> MotionExecutor:
    from drivenav.robot import ros

    return _with_ros(ros.RosMotionExecutor, "--motion", "cmd-vel")


def _held_still(args: argparse.Namespace, sim: SimConfig) -> MotionExecutor:
    from drivenav.robot.parts import HeldStill

    return HeldStill()


def _with_ros(part: Callable[[], T], option: str, value: str) -> T:
    """A live ROS 2 part, or one line saying that ROS 2 is not sourced."""
    try:
        return part()
    except RuntimeError as error:
        raise InputError("command line", option, f"a sourced ROS 2 install (rclpy) for {value}", str(error)) from None


ROS2_SOURCE = SourceEntry("ros2", "ROS 2 topics", _ros2_source)
BAG_SOURCE = SourceEntry("bag", "a ROS 2 bag (--bag)", _bag_source, _bag_options, ("--bag",))
CMD_VEL_MOTION = MotionEntry("cmd-vel", "cmd_vel on odometry", _cmd_vel_motion)
HELD_STILL = MotionEntry("none", "the robot held still (bag replays, bring-up)", _held_still)

BUILT_IN_SOURCES = {"ros2": "drivenav.robot.registry:ROS2_SOURCE", "bag": "drivenav.robot.registry:BAG_SOURCE"}
"""drivenav's own sensor sources (also declared in pyproject.toml, group ``drivenav.robot_sources``)."""

BUILT_IN_MOTIONS = {"cmd-vel": "drivenav.robot.registry:CMD_VEL_MOTION", "none": "drivenav.robot.registry:HELD_STILL"}
"""drivenav's own motion executors (also declared in pyproject.toml, group ``drivenav.robot_motions``)."""

SOURCES: Registry[SourceEntry] = Registry(
    "drivenav.robot_sources",
    BUILT_IN_SOURCES,
    lambda part: isinstance(part, SourceEntry),
    "sensor source entry (drivenav.robot.registry.SourceEntry)",
    "--source",
    named=lambda entry: entry.name,
)
"""Every sensor source by ``--source`` name: the built-ins, then plug-ins."""

MOTIONS: Registry[MotionEntry] = Registry(
    "drivenav.robot_motions",
    BUILT_IN_MOTIONS,
    lambda part: isinstance(part, MotionEntry),
    "motion executor entry (drivenav.robot.registry.MotionEntry)",
    "--motion",
    named=lambda entry: entry.name,
)
"""Every motion executor by ``--motion`` name: the built-ins, then plug-ins."""

DEFAULT_SOURCE = "ros2"
DEFAULT_MOTION = "cmd-vel"


def add_part_options(parser: argparse.ArgumentParser) -> None:
    """``--source`` and ``--motion``, each with its parts' own options (a plug-in that cannot be loaded, or whose
    options do not fit the command, is still a choice, refused with its one line when chosen). Called once the
    command's other options are in: a plug-in's options are checked against them all."""
    _add_choice(parser, SOURCES, DEFAULT_SOURCE, "sensors")
    _add_choice(parser, MOTIONS, DEFAULT_MOTION, "motion")


def _add_choice(parser: argparse.ArgumentParser, registry: Registry[Entry], default: str, what: str) -> None:
    entries = registry.usable()
    group = parser.add_argument_group(f"robot {what} ({registry.option})")
    shown = "; ".join(f"{name}: {entry.summary}" for name, entry in entries.items())
    group.add_argument(registry.option, default=default, choices=registry.names, help=f"{shown} (default {default})")
    add_options_of(parser, group, registry, {name: entry.add_options for name, entry in entries.items()})


def robot_parts(args: argparse.Namespace, sim: SimConfig) -> tuple[SensorSource, MotionExecutor]:
    """The sensor source and the motion executor named on the command line (``args.source``, ``args.motion``),
    built in that order once the other parts' own options are refused."""
    source = _chosen(SOURCES, args.source, args)
    motion = _chosen(MOTIONS, args.motion, args)
    with SOURCES.guard(source.name, "build"):
        sensors = source.build(args, sim)
    with MOTIONS.guard(motion.name, "build"):
        executor = motion.build(args, sim)
    return sensors, executor


def _chosen(registry: Registry[Entry], name: str, args: argparse.Namespace) -> Entry:
    """The part ``name`` of ``registry``; another part's own option in ``args`` is one line."""
    chosen = registry.chosen(args, name)
    for other in registry.offered(args).values():
        if other is not chosen:
            refuse_options(args, other.own_options, f"only with {registry.option} {other.name}")
    return chosen
