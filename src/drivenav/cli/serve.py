"""``drivenav serve grounder``: one copy of a grounder served to every worker, with dynamic batching (issue 37).

Workers reach it with ``--detector remote --detector-url ENDPOINT``; ``eval --share-detector`` starts one itself.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

from drivenav.cli.common import Commands, add_segmenter_options
from drivenav.errors import InputError
from drivenav.eval.options import path

if TYPE_CHECKING:
    from drivenav.semantics.model_spec import ModelSpec
    from drivenav.semantics.protocols import Grounder
    from drivenav.semantics.serve_config import ServeConfig


def add_serve(commands: Commands) -> None:
    from drivenav.semantics.model_spec import DTYPES
    from drivenav.semantics.registry import GROUNDER_BACKENDS
    from drivenav.semantics.serve_config import DEFAULT_BIND, MAX_BATCH, MAX_BATCH_MS, MAX_COPIES, ServeConfig

    default = ServeConfig()
    parser = commands.add_parser("serve", help="serve a model to every worker: serve grounder")
    sub = parser.add_subparsers(dest="serve_command", required=True)
    grounder = sub.add_parser(
        "grounder", help="one grounder copy for every worker (--detector remote), batching their frames"
    )
    local = [name for name in GROUNDER_BACKENDS.names if name != "remote"]
    grounder.add_argument("--detector", required=True, choices=local, help="the grounder served")
    grounder.add_argument(
        "--detector-model", default="", help="checkpoint dir or HF-cache model id (SAM3, OWLv2, Grounding DINO)"
    )
    add_segmenter_options(grounder, own_defaults=True)
    grounder.add_argument("--device", default="", help="cpu or cuda (default: cuda when visible)")
    grounder.add_argument("--dtype", choices=DTYPES, default="auto", help="default auto: bf16 on CUDA, else fp32")
    grounder.add_argument("--compile", action="store_true", help="torch.compile the models' per-frame modules")
    grounder.add_argument(
        "--random-weights",
        action="store_true",
        help="the full-size architectures with random weights, no checkpoint (throughput benchmarks: the detections "
        "are noise)",
    )
    grounder.add_argument("--tiny", action="store_true", help="the tests' tiny random models (a smoke test)")
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
    grounder.add_argument(
        "--copies",
        type=int,
        default=default.copies,
        help=f"copies of the model, each in a thread of its own, 1-{MAX_COPIES} (default {default.copies}; more "
        "fill a GPU that one leaves idle)",
    )
    grounder.set_defaults(handler=_cmd_serve_grounder)


def _cmd_serve_grounder(args: argparse.Namespace) -> int:
    from drivenav.semantics.grounder_server import build_server, run_server
    from drivenav.semantics.model_spec import ModelSpec
    from drivenav.semantics.registry import check_models
    from drivenav.wire.security import check_bind

    check_bind(args.bind, args.keys)  # before the model loads
    config = serve_config(args.batch, args.batch_ms, args.copies)
    _refuse_model_options(args)
    spec = ModelSpec(
        detector=args.detector,
        detector_model=args.detector_model,
        dtype=args.dtype,
        detector_device=args.device,
        segmenter=args.segmenter,
        segmenter_model=args.segmenter_model,
        compile=args.compile,
    )
    build, described = _random_build(args)
    if build is None:  # random weights need no checkpoint
        check_models(spec, connect=False)
    try:
        run_server(build_server(spec, args.bind, args.keys, config, build, described), args.keys is not None)
    except KeyboardInterrupt:
        print("drivenav: stopped serving the grounder", file=sys.stderr)
        return 130
    return 0


def serve_config(batch: int, batch_ms: float, copies: int) -> ServeConfig:
    """A server's batching and copies from the command line (``--batch``, ``--batch-ms``, ``--copies``), each out
    of its range one line."""
    from drivenav.semantics.serve_config import MAX_BATCH, MAX_BATCH_MS, MAX_COPIES, ServeConfig

    if not 1 <= batch <= MAX_BATCH:
        raise InputError("command line", "--batch", f"a number of frames from 1 to {MAX_BATCH}", batch)
    if not (math.isfinite(batch_ms) and 0.0 <= batch_ms <= MAX_BATCH_MS):
        expected = f"a number of milliseconds from 0 to {MAX_BATCH_MS:g} (the longest a request waits for its batch)"
        raise InputError("command line", "--batch-ms", expected, batch_ms)
    if not 1 <= copies <= MAX_COPIES:
        raise InputError("command line", "--copies", f"a number of model copies from 1 to {MAX_COPIES}", copies)
    return ServeConfig(batch=batch, batch_ms=batch_ms, copies=copies)


def _random_build(args: argparse.Namespace) -> tuple[Callable[[ModelSpec], Grounder] | None, str]:
    """With ``--random-weights`` or ``--tiny``: the grounder's builder with random weights and its description;
    else none (the detector's backend loads its checkpoint)."""
    if not (args.random_weights or args.tiny):
        return None, ""
    from drivenav.semantics.registry import MODEL_DETECTORS

    given = "--tiny" if args.tiny else "--random-weights"
    if args.detector not in MODEL_DETECTORS:
        raise _model_detector_only(given, args.detector)
    if args.detector_model or args.segmenter_model:
        raise InputError("command line", given, "no --detector-model or --segmenter-model", "a checkpoint")
    try:
        from drivenav.semantics.random_grounders import random_grounder
    except ImportError as error:
        extra = f"the models extra for {args.detector} (pip install 'drivenav[models]')"
        raise InputError("command line", "--detector", extra, str(error).splitlines()[0]) from None
    return partial(random_grounder, tiny=args.tiny), "tiny random weights" if args.tiny else "random weights"


def _refuse_model_options(args: argparse.Namespace) -> None:
    """A detector that loads no model (the embedded one, ground truth: not
    :func:`~drivenav.semantics.serve_config.takes_model_options`) honours none of the model options: the first one
    given is refused in one line naming it, as ``--tiny`` is, never ignored."""
    from drivenav.semantics.serve_config import takes_model_options

    if takes_model_options(args.detector):
        return
    given = first_model_option(args) or ("--copies" if args.copies != 1 else None)
    if given is not None:
        raise _model_detector_only(given, args.detector)


def first_model_option(args: argparse.Namespace) -> str | None:
    """The first of the options that choose and place a model (``--detector-model``, ``--device``, ``--dtype``,
    ``--compile``, ``--segmenter``, ``--segmenter-model``, ``--random-weights``, ``--tiny``) given a value of its
    own, or None: what a command serving no model refuses."""
    from drivenav.semantics.registry import DEFAULT_SEGMENTER

    options = (
        ("--detector-model", args.detector_model, ""),
        ("--device", args.device or "", ""),
        ("--dtype", args.dtype, "auto"),
        ("--compile", args.compile, False),
        ("--segmenter", args.segmenter, DEFAULT_SEGMENTER),
        ("--segmenter-model", args.segmenter_model, ""),
        ("--random-weights", args.random_weights, False),
        ("--tiny", args.tiny, False),
    )
    return next((option for option, value, unset in options if value != unset), None)


def _model_detector_only(option: str, detector: str) -> InputError:
    """The line for ``option``, which only a model detector honours, given with ``detector``."""
    from drivenav.semantics.registry import MODEL_DETECTORS

    expected = f"a model detector ({', '.join(MODEL_DETECTORS)}) with {option}"
    return InputError("command line", option, expected, detector)
