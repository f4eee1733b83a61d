"""``drivenav report RUN [RUN ...] --out DIR``: runs, their comparison and every episode as a static HTML site."""

from __future__ import annotations

import argparse
from pathlib import Path

from drivenav.cli.common import Commands
from drivenav.errors import InputError
from drivenav.eval.options import path, positive

PICTURE_CHOICES = ("failures", "all", "none")


def add_report(commands: Commands) -> None:
    parser = commands.add_parser(
        "report", help="a static HTML site of runs and their episodes (open DIR/index.html in a browser)"
    )
    parser.add_argument("runs", type=path, nargs="+", metavar="RUN", help="run directories (drivenav eval --out)")
    parser.add_argument("--out", type=path, required=True, help="the site's folder")
    parser.add_argument(
        "--pictures", choices=PICTURE_CHOICES, default="failures", help="episodes whose missing pictures are drawn"
    )
    parser.add_argument("--max-pictures", type=int, default=None, help="draw at most N pictures per run")
    parser.add_argument("--views", action="store_true", help="draw drivenav viz's whole pictures (slower)")
    parser.add_argument("--workers", type=int, default=2, help="processes writing pages and pictures (default 2)")
    parser.set_defaults(handler=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from drivenav.report.config import PictureChoice, ReportConfig
    from drivenav.report.site import write_report

    if args.max_pictures is not None and args.max_pictures < 0:
        raise InputError("command line", "--max-pictures", "a number of pictures >= 0", args.max_pictures)
    config = ReportConfig(
        PictureChoice(args.pictures), args.max_pictures, args.views, positive(args.workers, "--workers")
    )
    index = write_report(list(args.runs), args.out, config)
    print(f"report: {Path(index).resolve()}")
    return 0
