"""``drivenav serve grounder``: one copy of a grounder served to every worker, with dynamic batching (issue 37).

Workers reach it with ``--detector remote --detector-url ENDPOINT``; ``eval --share-detector`` starts one itself.
"""

from __future__ import annotations

import argparse
import math
import sys

from drivenav.cli.common import Commands
from drivenav.errors import InputError
from drivenav.eval.options import path


def add_serve(commands: Commands) -> None:
    from drivenav.semantics.registry import DTYPES, GROUNDER_BACKENDS
    from drivenav.semantics.serve_config import DEFAULT_BIND, MAX_BATCH, MAX_BATCH_MS, ServeConfig

    default = ServeConfig()
    parser = commands.add_parser("serve", help="serve a model to every worker: serve grounder")
    sub = parser.add_subparsers(dest="serve_command", required=True)
    grounder = sub.add_parser(
        "grounder", help="one grounder copy for every worker (--detector remote), batching their frames"
    )
    local = [name for name in GROUNDER_BACKENDS.names if name != "remote"]
    grounder.add_argument("--detector", required=True, choices=local, help="the grounder served")
    grounder.add_argument("--detector-model", default="", help="checkpoint dir or HF-cache model id (SAM3, OWLv2)")
    grounder.add_argument("--device", default="", help="cpu or cuda (default: cuda when visible)")
    grounder.add_argument("--dtype", choices=DTYPES, default="auto", help="default auto: bf16 on CUDA, else fp32")
    grounder.add_argument(
        "--bind", default=DEFAULT_BIND, help=f"endpoint (default {DEFAULT_BIND}; port * for a free one)"
    )
    grounder.add_argument("--keys", type=path, default=None, help="CURVE keys (required off loopback)")
    grounder.add_argument(
        "--batch", type=int, default=default.batch, help=f"frames a batch, 1-{MAX_BATCH} (default {default.batch})"
    )
    grounder.add_argument(
        "--batch-ms",
        type=float,
        default=default.batch_ms,
        help=f"the longest a request waits for its batch to fill, 0-{MAX_BATCH_MS:g} ms (default {default.batch_ms:g})",
    )
    grounder.set_defaults(handler=_cmd_serve_grounder)


def _cmd_serve_grounder(args: argparse.Namespace) -> int:
    from drivenav.semantics.grounder_server import run_server
    from drivenav.semantics.registry import ModelSpec
    from drivenav.semantics.serve_config import MAX_BATCH, MAX_BATCH_MS, ServeConfig
    from drivenav.wire.security import check_bind

    check_bind(args.bind, args.keys)  # before the model loads
    if not 1 <= args.batch <= MAX_BATCH:
        raise InputError("command line", "--batch", f"a number of frames from 1 to {MAX_BATCH}", args.batch)
    if not (math.isfinite(args.batch_ms) and 0.0 <= args.batch_ms <= MAX_BATCH_MS):
        expected = f"a number of milliseconds from 0 to {MAX_BATCH_MS:g} (the longest a request waits for its batch)"
        raise InputError("command line", "--batch-ms", expected, args.batch_ms)
    config = ServeConfig(batch=args.batch, batch_ms=args.batch_ms)
    spec = ModelSpec(
        detector=args.detector, detector_model=args.detector_model, dtype=args.dtype, detector_device=args.device
    )
    try:
        run_server(spec, args.bind, args.keys, config)
    except KeyboardInterrupt:
        print("drivenav: stopped serving the grounder", file=sys.stderr)
        return 130
    return 0
