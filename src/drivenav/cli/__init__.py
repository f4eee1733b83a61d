"""The ``drivenav`` command line: evaluation, episode generation, benchmarks, pictures and the demo.

Bad input (files, fields, options) prints one line naming what was wrong and exits with status 2.
"""

# One module per command group (evaluate, episodes, bench, robot); what they share is in common. Every module
# imports its heavy dependencies inside the handlers, so that building the parser loads no numerical module.

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
from collections.abc import Sequence

from drivenav.cli.bench import RESUMABLE as BENCH_RESUMABLE
from drivenav.cli.bench import add_bench, add_benchmark
from drivenav.cli.common import Handler
from drivenav.cli.episodes import add_episodes
from drivenav.cli.evaluate import RESUMABLE as EVAL_RESUMABLE
from drivenav.cli.evaluate import add_compare, add_config, add_demo, add_doctor, add_eval, add_run, add_viz
from drivenav.cli.report import add_report
from drivenav.cli.robot import SERVING, add_robot
from drivenav.cli.serve import add_serve
from drivenav.errors import InputError, RunStoppedError, WorkerDiedError
from drivenav.plugins import handle_stop_signals
from drivenav.threads import limit_blas_threads

limit_blas_threads()  # before numpy loads: nothing above imports it, the command handlers do

COMMANDS = (
    add_eval,
    add_run,
    add_config,
    add_episodes,
    add_benchmark,
    add_bench,
    add_viz,
    add_compare,
    add_demo,
    add_report,
    add_robot,
    add_serve,
    add_doctor,
)
"""Each command group's parser, in the order ``--help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="drivenav", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true")
    commands = parser.add_subparsers(dest="command", required=True)
    for add in COMMANDS:
        add(commands)
    return parser


def _shown_path(error: OSError) -> str:
    """A path in an error line, shortened when it is very long."""
    name = str(error.filename)
    return name if len(name) <= 200 else f"{name[:100]}...{name[-60:]} ({len(name)} characters)"


RESUMABLE = (*EVAL_RESUMABLE, *BENCH_RESUMABLE)
"""The handlers that write a run directory episode by episode: an interrupted one resumes when run again."""

PIPE_CLOSED = 128 + signal.SIGPIPE
"""The exit status when the reader of the output went away (``drivenav ... | head``), as a shell reports a command
ended by SIGPIPE."""


def _interrupted(handler: Handler) -> str:
    """What Ctrl-C (or SIGTERM) left behind, in the words of the command it stopped."""
    if handler in SERVING:
        return "interrupted (stopped serving (the robot is halted))"
    if handler in RESUMABLE:
        return "interrupted (finished episodes are saved; rerun to resume)"
    return "interrupted"


def _reader_gone() -> int:
    """Standard output's reader closed the pipe: nothing more can be shown, and the exit flush must not fail on it."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return PIPE_CLOSED


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; the exit status: 0 done, 1 a run stopped or a check failed, 2 bad input, 130 interrupted,
    141 the output's reader went away."""
    handle_stop_signals()  # SIGTERM behaves like Ctrl-C (finished episodes stay saved); a plug-in's own is no stop
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    handler: Handler = args.handler
    try:
        status = handler(args)
        sys.stdout.flush()  # a closed pipe is found here, not in the interpreter's exit
        return status
    except BrokenPipeError:  # an OSError without a file name: before that clause
        return _reader_gone()
    except InputError as error:
        print(f"drivenav: error: {error}", file=sys.stderr)
        return 2
    except (WorkerDiedError, RunStoppedError) as error:
        print(f"drivenav: error: {error}", file=sys.stderr)
        return 1
    except OSError as error:  # a path given that cannot be written or read (a folder, too long, under /proc)
        if error.filename is None:
            raise
        print(f"drivenav: error: {_shown_path(error)}: {error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"drivenav: {_interrupted(handler)}", file=sys.stderr)
        return 130
