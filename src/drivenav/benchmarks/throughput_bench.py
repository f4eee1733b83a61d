"""``drivenav bench eval-throughput``: a real ``drivenav eval`` beside one served grounder, and where a step's time
goes (issue 61).

The grounder (SAM3, OWLv2 or Grounding DINO with their box segmenter; random weights, full size or the tests' tiny
ones, as ``bench grounder`` builds them) is served from this process on loopback
(:class:`~drivenav.semantics.grounder_server.GrounderServer`: a socket thread and a model thread). The eval's
workers act on the embedded detector's detections, and every frame they ground is also sent to the served model and
waited for (``--detector-shadow-url``): each step pays the model's wire, batch and forward, and the records are
those of a plain run (random weights would give noise).

What it says: the eval's rate (episodes an hour, frames a second, over its wall time, start-up included) and where
the time went, on both sides of the wire. A worker's step (its wall time: the eval's wall time times the workers
over the frames) splits into the agent's compute (mapping, directions, inspection, value maps, fusion, policy:
the traces' per-step timings), its grounding (the embedded detector and the served model's round trip, as one
timed step of the agent) and the rest (rendering the world, the runner, the pool). The server's share comes from
its :class:`~drivenav.semantics.serve_pipeline.ServerTimes`: each stage's milliseconds a frame, the mean batch,
what serving adds to a frame beyond the grounder's own stages, and ``model_busy``, the share of the wall time
the grounder's own stages kept the model busy (1.0: the model is the bottleneck).

``--forward-ms MS`` serves :class:`WaitingGrounder` instead of a model: a forward that waits ``MS`` and computes
nothing, as a GPU's forward looks to its host. On a machine without one it measures serving and the workers (what
overlaps, how batches form) without a model's compute competing with the workers for the CPU.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.report import Throughput, summarize
from drivenav.eval.rundir import EPISODES_FILE, SUMMARY_FILE, trace_path
from drivenav.eval.timings import COMPUTE_KEYS
from drivenav.eval.trace import EpisodeTrace, read_trace
from drivenav.semantics.protocols import Detection
from drivenav.semantics.serve_pipeline import MODEL_STAGES, ServerTimes, Steady
from drivenav.types import GroundTruth, Observation

if TYPE_CHECKING:
    from drivenav.semantics.grounder_bench import GrounderBenchOptions
    from drivenav.semantics.protocols import Grounder
    from drivenav.semantics.serve_config import ServeConfig

WAITING: Final[str] = "wait"
"""The detector name of :class:`WaitingGrounder` (``--forward-ms``) in the bench's figures."""
INTERRUPTED: Final[int] = 130
"""The exit status of an eval stopped by Ctrl-C or SIGTERM (its finished episodes saved)."""
GROUNDING_KEY: Final[str] = "grounding"
"""The traces' per-step timing of the agent's grounding (the detector's call, a served model's round trip)."""


@dataclass(frozen=True)
class WorkerSteps:
    """A worker's milliseconds a step, on average over the run's steps: its wall time, the agent's compute, its
    grounding, and the rest (rendering, the runner)."""

    wall_ms: float
    agent_ms: float
    grounding_ms: float
    other_ms: float


@dataclass(frozen=True)
class ThroughputResult:
    """An eval beside a served grounder (module docstring). ``steady_frames_per_second``: the frames a second the
    server took while every worker was grounding, over ``steady_window_s`` seconds (None for a window under 10 s:
    :class:`~drivenav.semantics.serve_pipeline.SteadyRate`); ``stopped``: what stopped the eval before its end
    (``window``: ``--window``; ``signal``: Ctrl-C, SIGTERM), its figures then those of the episodes it finished;
    ``frames_served``: the requests the server answered (one a phrase: ApexNav sends a frame for several);
    ``encodings_per_frame``: the images its forwards encoded a frame it received
    (:meth:`~drivenav.semantics.serve_pipeline.ServerTimes.encodings_per_frame`); ``server_stages_ms``:
    milliseconds a frame by stage; ``server_added_ms``: what serving adds to a frame beyond the grounder's
    stages."""

    detector: str
    model: str
    device: str
    dtype: str
    workers: int
    batch: int
    batch_ms: float
    copies: int
    episodes: int
    errors: int
    frames: int
    wall_s: float
    episodes_per_hour: float | None
    frames_per_second: float | None
    steady_frames_per_second: float | None
    steady_window_s: int | None
    stopped: str | None
    worker_step: WorkerSteps | None
    frames_served: int
    encodings_per_frame: float | None
    mean_batch: float | None
    server_stages_ms: dict[str, float]
    server_added_ms: float | None
    model_busy: float | None
    run_dir: str


def worker_steps(traces: Iterable[EpisodeTrace], workers: int, wall_s: float) -> WorkerSteps | None:
    """The mean step of the run's ``workers`` over ``wall_s`` seconds, from its traces' per-step timings (None
    without a timed step)."""
    agent = grounding = 0.0
    steps = 0
    for trace in traces:
        columns = trace.step_ms
        length = max((len(values) for values in columns.values()), default=0)
        steps += length
        agent += sum(sum(columns.get(key, ())) for key in COMPUTE_KEYS)
        grounding += sum(columns.get(GROUNDING_KEY, ()))
    if not steps:
        return None
    wall_ms = 1000.0 * wall_s * workers / steps
    agent_ms, grounding_ms = agent / steps, grounding / steps
    return WorkerSteps(*(round(ms, 3) for ms in (wall_ms, agent_ms, grounding_ms, wall_ms - agent_ms - grounding_ms)))


def model_busy(times: ServerTimes, wall_s: float) -> float | None:
    """The share of ``wall_s`` the grounder's own stages took on the server (None for no time)."""
    if wall_s <= 0:
        return None
    return round(sum(times.seconds[stage] for stage in MODEL_STAGES) / wall_s, 3)


def run_traces(run_dir: Path, records: Iterable[EpisodeRecord]) -> list[EpisodeTrace]:
    """The traces of the run's finished episodes, its ``records`` (a torn or missing trace is left out)."""
    read = (read_trace(trace_path(run_dir, record.episode_id)) for record in records)
    return [trace for trace in read if trace is not None]


@dataclass(frozen=True)
class ServedModel:
    """The served grounder of the bench: what it is (``detector``, ``model``, ``device``, ``dtype``) and its
    server's batching."""

    detector: str
    model: str
    device: str
    dtype: str
    batch: int
    batch_ms: float
    copies: int


def throughput_result(
    served: ServedModel, server: ServerFigures, run_dir: Path, workers: int, wall_s: float, stopped: str | None = None
) -> ThroughputResult:
    """The bench's figures from the eval in ``run_dir`` and its server's: a worker's step and the model's busy share
    over the eval's own wall time (its summary's rate), ``wall_s`` the bench's (start-up included). An
    eval ``stopped`` wrote no summary: its rate is its finished episodes' over ``wall_s``."""
    times = server.times
    records = read_records(run_dir / EPISODES_FILE)
    traces = run_traces(run_dir, records)
    frames = sum(len(trace.actions) for trace in traces)
    summary = (
        summarize(records, Throughput(len(records), frames, wall_s)).to_json() if stopped else read_summary(run_dir)
    )
    rate = summary.get("frames_per_second")
    eval_s = frames / rate if isinstance(rate, (int, float)) and rate > 0 else wall_s
    steady = server.steady
    return ThroughputResult(
        detector=served.detector,
        model=served.model,
        device=served.device,
        dtype=served.dtype,
        workers=workers,
        batch=served.batch,
        batch_ms=served.batch_ms,
        copies=served.copies,
        episodes=int(summary["episodes"]),
        errors=int(summary["errors"]),
        frames=frames,
        wall_s=round(wall_s, 3),
        episodes_per_hour=summary.get("episodes_per_hour"),
        frames_per_second=summary.get("frames_per_second"),
        steady_frames_per_second=None if steady is None else steady.frames_per_second,
        steady_window_s=None if steady is None else steady.window_s,
        stopped=stopped,
        worker_step=worker_steps(traces, workers, eval_s),
        frames_served=times.frames,
        encodings_per_frame=times.encodings_per_frame(),
        mean_batch=round(times.frames / times.batches, 2) if times.batches else None,
        server_stages_ms=times.per_frame_ms(),
        server_added_ms=times.added_ms(),
        model_busy=model_busy(times, eval_s),
        run_dir=str(run_dir),
    )


def read_summary(run_dir: Path) -> dict[str, Any]:
    """The finished eval's ``summary.json``."""
    summary: dict[str, Any] = json.loads((run_dir / SUMMARY_FILE).read_text(encoding="utf-8"))
    return summary


class ServerFigures(Protocol):
    """What the bench reads of its server when the eval is over."""

    @property
    def times(self) -> ServerTimes: ...

    @property
    def steady(self) -> Steady | None: ...


def run_for(run: Callable[[], int], window_s: float | None) -> tuple[int, bool]:
    """``run()``'s exit status, and whether the window stopped it: with ``window_s``, the eval it runs is stopped
    that many seconds after it starts, as Ctrl-C stops it (the eval's own handling: the episodes it finished saved,
    :data:`INTERRUPTED`). The stop is a SIGINT sent to this process's main thread, which runs its handler: sent to
    the process from the timer's thread, the main thread, blocked waiting for an episode, would see it only when the
    next episode ended (seconds late). One that comes as the eval ends, after it returned, is caught here: the eval
    then counts as stopped, its figures still those of its records."""
    if window_s is None:
        return run(), False
    fired = threading.Event()
    main = threading.main_thread().ident
    assert main is not None

    def stop() -> None:
        fired.set()
        signal.pthread_kill(main, signal.SIGINT)  # to the main thread: a wait it is blocked in ends at once

    timer = threading.Timer(window_s, stop)
    timer.start()
    try:
        try:
            status = run()
        finally:
            timer.cancel()
            timer.join()  # the handler of a stop sent meanwhile runs here at the latest, inside this try
    except KeyboardInterrupt:
        if not fired.is_set():
            raise
        status = INTERRUPTED
    return status, fired.is_set()


RunEval = Callable[[str, Path], int]
"""Runs the eval with its detector shadowed by the server at the endpoint given, into the run directory given;
returns its exit status."""


class WaitingGrounder:
    """A model's stand-in that measures serving and the workers without a model's compute (``--forward-ms``): each
    batch's forward is ``forward_ms`` milliseconds of waiting, whatever its size (a GPU's time as its host sees it,
    below the GPU's saturation), and it finds nothing. It batches as a served SAM3 does
    (:class:`~drivenav.semantics.serve_pipeline.RowGrounder`: every phrase of a batch in one forward)."""

    name = WAITING

    def __init__(self, forward_ms: float) -> None:
        self.forward_ms = forward_ms

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Nothing to begin: it reads no ground truth and holds no text features."""

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        return self.segment_batch([observation.rgb], phrase)[0]

    def segment_batch(self, frames: Sequence[NDArray[np.uint8]], phrase: str) -> list[list[Detection]]:
        return self.segment_rows(self.preprocess(frames), frames, [(i, phrase) for i in range(len(frames))])

    def preprocess(self, frames: Sequence[NDArray[np.uint8]]) -> int:
        """Nothing to prepare: the number of frames stands for their pixels."""
        return len(frames)

    def join_pixels(self, parts: Sequence[int]) -> int:
        """Frames preprocessed apart, joined: their number."""
        return sum(parts)

    def segment_rows(
        self,
        pixels: Any,
        frames: Sequence[NDArray[np.uint8]],
        rows: Sequence[tuple[int, str]],
        lap: Callable[[str], None] | None = None,
    ) -> list[list[Detection]]:
        time.sleep(self.forward_ms / 1000.0)
        if lap is not None:
            lap("forward")
        return [[] for _ in rows]


def _served_model(
    options: GrounderBenchOptions, config: ServeConfig, forward_ms: float
) -> tuple[ServedModel, Callable[[], Grounder]]:
    """What the bench serves and the server's factory of its copies: ``options``' model, or with ``forward_ms`` a
    :class:`WaitingGrounder`."""
    from drivenav.semantics.grounder_server import probe_first

    batching = (config.batch, config.batch_ms, config.copies)
    if forward_ms > 0.0:
        model = f"a {forward_ms:g} ms wait a batch, no compute"
        return ServedModel(WAITING, model, "none", "none", *batching), partial(WaitingGrounder, forward_ms)
    from drivenav.semantics.grounder_bench import bench_model
    from drivenav.semantics.hf_common import pick_device, resolve_dtype

    device = pick_device(options.device)
    grounder, model = bench_model(options, device)
    dtype = str(resolve_dtype(options.dtype, device)).removeprefix("torch.")

    def build() -> Grounder:
        return bench_model(options, device)[0]

    return ServedModel(options.detector, model, device, dtype, *batching), probe_first(grounder, build)


def served_eval(
    options: GrounderBenchOptions,
    config: ServeConfig,
    workers: int,
    run_dir: Path,
    run_eval: RunEval,
    forward_ms: float = 0.0,
    window_s: float | None = None,
) -> ThroughputResult:
    """``options``' model (with ``forward_ms`` > 0, a :class:`WaitingGrounder` instead) served as ``config`` says
    (its batching, its copies) beside the eval ``run_eval`` runs into ``run_dir`` with ``workers`` workers, stopped
    ``window_s`` seconds after it starts where given (:func:`run_for`); an eval that fails is an
    :class:`~drivenav.errors.InputError`."""
    from drivenav.semantics.grounder_server import GrounderServer, serving
    from drivenav.semantics.served import ServedInfo

    served, factory = _served_model(options, config, forward_ms)
    info = ServedInfo(
        served.detector, served.model, served.device, served.dtype, ("rgb",), False, config.batch, config.batch_ms
    )
    server = GrounderServer(factory, info, "tcp://127.0.0.1:*", None, config)
    with serving(server) as endpoint:
        start = time.perf_counter()
        status, windowed = run_for(lambda: run_eval(endpoint, run_dir), window_s)
        wall_s = time.perf_counter() - start
    if status not in (0, INTERRUPTED):
        expected = f"an eval that runs (exit 0) or is stopped (exit {INTERRUPTED})"
        raise InputError("command line", "eval-throughput -- ...", expected, f"exit {status}")
    stopped = ("window" if windowed else "signal") if status == INTERRUPTED else None
    return throughput_result(served, server, run_dir, workers, wall_s, stopped)
