"""The example robot parts as ``drivenav robot serve`` sees them: ``--source frames`` (with its own ``--frames``
option) and ``--motion printed``, each a light entry (:class:`~drivenav.robot.registry.SourceEntry`,
:class:`~drivenav.robot.registry.MotionEntry`) named by one entry point (groups ``drivenav.robot_sources`` and
``drivenav.robot_motions``). This module is imported whenever ``drivenav robot serve`` is set up, so the parts
themselves (:mod:`.frames`) are imported when they are built."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.robot.registry import MotionEntry, SourceEntry

if TYPE_CHECKING:
    from drivenav.robot.parts import MotionExecutor, SensorSource
    from drivenav.types import SimConfig


def _frames_options(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--frames", type=Path, default=None, help="with --source frames: a folder of .npz frames")


def _frames(args: argparse.Namespace, sim: SimConfig) -> SensorSource:
    """The frames of ``--frames``, seen through the camera the robot says it has (``sim``)."""
    from drivenav_example.frames import FolderSource

    if args.frames is None or not args.frames.is_dir():
        raise InputError("command line", "--frames", "a folder of .npz frames with --source frames", args.frames)
    return FolderSource(args.frames, sim.intrinsics)


def _printed(args: argparse.Namespace, sim: SimConfig) -> MotionExecutor:
    from drivenav_example.frames import PrintedMotion

    return PrintedMotion()


FRAMES = SourceEntry("frames", "frames replayed from a folder of .npz files", _frames, _frames_options, ("--frames",))
PRINTED = MotionEntry("printed", "each action printed, nothing moves", _printed)
