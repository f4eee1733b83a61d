"""``drivenav bench grounder``: how long the SAM3, OWLv2 or Grounding DINO grounder (with its box segmenter) takes
on a 640x480 frame, in process and served.

Weights are not needed: without a checkpoint (or with ``--random-weights``) the model is the full-size
architecture of transformers' default configuration with random weights (:mod:`drivenav.semantics.random_grounders`;
MobileSAM's ``vit_t`` without ``--segmenter-model``), which costs the same time as the released one. ``--tiny``
uses the tests' tiny configurations instead (a smoke test of the bench itself; its times measure nothing but the
plumbing). ``--compile`` compiles the per-frame modules (``models.compile``); they compile during the untimed frames.

Each timed frame is new (its vision features are computed), the phrase is the same (its text features are encoded
once, as in an episode); frames are random pixels. One frame is split into the grounder's stages: preprocessing
(:meth:`~drivenav.semantics.hf_common.TransformersGrounder.preprocess`), forward (vision features and decoding) and
postprocessing (masks at the frame's size, detections); ``segment_ms`` is the part of postprocessing that a box
detector's segmenter takes (MobileSAM's encoder and decoder; null for SAM3, which makes its own masks), on as many
boxes as the detector passed (the notes give their median: random weights pass many). ``detections_per_frame``: the
median of the detections a timed frame gave (each one's mask is copied, checked and packed when served: random
weights give more than a trained model, which the reply's cost follows). On CUDA every stage ends with a
synchronisation.

``--clients K`` also times the served path (:mod:`drivenav.semantics.grounder_server`), with the grounder served
from this process on loopback: ``served_ms_per_frame`` is the throughput of K client threads each grounding
``frames`` frames one after another through a server batching up to K frames (wall time over every frame; with
``--phrases P`` the clients look for P different objects, as an eval's workers do, client ``i`` for the
``(i mod P)``-th of :data:`CLIENT_PHRASES`; ``client_phrases`` says how many), and
``served_overhead_ms`` is what serving adds to one frame at batch 1 (one client, a server that never waits: the
median latency of a served frame minus that of the same frame in process, both through ``segment_batch``). The
clients share this process with the server, so on a CPU they also compete for its cores.

Where a served frame's time goes (issue 61), from the K clients' run: ``served_stages_ms``, the server's
milliseconds a frame by stage (:class:`~drivenav.semantics.serve_pipeline.ServerTimes`: decoding the request, the
wait for its batch, the grounder's preprocessing, forward and postprocessing, the reply's check, mask packing and
encoding, and its sending), ``served_added_ms`` what serving adds to a frame's busy time beyond the grounder's
own stages, ``served_mean_batch`` the mean batch; and a client's own share, ``client_encode_ms`` (a SEGMENT of a
640x480 frame made and encoded) and ``client_decode_ms`` (a DETECTIONS of the frame's detections decoded and its
masks unpacked).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.semantics.boxes import BoxGrounder, BoxSegmenter
from drivenav.semantics.hf_common import (
    COMPILE_BACKEND,
    DETECTOR_OPTION,
    TransformersGrounder,
    compile_backend_for,
    pick_device,
    resolve_dtype,
)
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.registry import BOX_DETECTORS, DEFAULT_SEGMENTER, make_segmenter
from drivenav.semantics.serve_pipeline import ServerTimes
from drivenav.types import CameraIntrinsics, Observation, Pose
from drivenav.wire.protocol import Message

FRAME_HEIGHT: Final[int] = 480
FRAME_WIDTH: Final[int] = 640
"""Issue 37's frame, the HM3D-OVON / Habitat ObjectNav camera's 640x480."""
WARMUP_FRAMES: Final[int] = 2
"""Untimed frames first: lazy initialisation, allocator growth, kernel selection."""
PHRASE: Final[str] = "chair"
CLIENT_PHRASES: Final[tuple[str, ...]] = (
    PHRASE,
    "bed",
    "sofa",
    "toilet",
    "tv monitor",
    "potted plant",
    "fire extinguisher",
    "refrigerator",
    "bathtub",
    "towel",
    "lamp",
    "sink",
    "fireplace",
    "picture",
    "clothes",
    "kitchen counter",
)
"""The objects ``--phrases K`` gives the served path's clients, client ``i`` the ``(i mod K)``-th (the first
HM3D-OVON-like categories that come to mind: an eval's workers each look for their own episode's object)."""
BENCH_HFOV_DEG: Final[float] = 79.0
"""The HM3D-OVON camera's horizontal field of view (the served frame's intrinsics; the grounders do not read it)."""
SERVED_NOTE: Final[str] = "served_ms_per_frame: --clients K times the served path (one model copy, K workers)"
OVERHEAD_FRAMES: Final[int] = 2
"""Untimed frames through a fresh server first (its text cache, the sockets' connection)."""
CODEC_REPEATS: Final[int] = 20
"""Repeats of a client's encoding and decoding, timed apart from the served run."""


@dataclass(frozen=True)
class GrounderBenchOptions:
    """What ``bench grounder`` runs. ``checkpoint``: a checkpoint directory or cached model id; empty for the
    detector's default one when it is in the Hugging Face cache, else random weights. ``segmenter``: a box
    detector's segmenter, MobileSAM from ``segmenter_checkpoint`` or with random weights. ``random_weights`` /
    ``tiny``: random weights whatever is cached, on the full-size / tiny configurations. ``device``: None for CUDA
    when visible. ``compile``: ``models.compile``. ``batch`` > 1 adds a batched forward of that many frames;
    ``clients`` > 0 the served path with that many concurrent clients, looking for ``phrases`` different objects
    (:data:`CLIENT_PHRASES`)."""

    detector: str = "sam3"
    checkpoint: str = ""
    segmenter: str = DEFAULT_SEGMENTER
    segmenter_checkpoint: str = ""
    random_weights: bool = False
    tiny: bool = False
    device: str | None = None
    dtype: str = "auto"
    compile: bool = False
    frames: int = 10
    batch: int = 1
    clients: int = 0
    phrases: int = 1

    def spec(self, device: str) -> ModelSpec:
        """The models' settings these options make, on ``device``."""
        return ModelSpec(
            detector=self.detector,
            detector_model=self.checkpoint,
            segmenter=self.segmenter,
            segmenter_model=self.segmenter_checkpoint,
            dtype=self.dtype,
            detector_device=device,
            compile=self.compile,
        )


@dataclass(frozen=True)
class GrounderBenchResult:
    """Per-frame milliseconds (medians over the timed frames; ``p90_ms`` the 90th percentile of the whole), the
    setting they were measured in, and GPU memory (peak allocated, MiB; None on the CPU). The served figures (module
    docstring) are None without clients."""

    detector: str
    model: str
    device: str
    dtype: str
    image_processor: str
    frames: int
    frame: str
    median_ms: float
    p90_ms: float
    preprocess_ms: float
    forward_ms: float
    postprocess_ms: float
    segment_ms: float | None
    detections_per_frame: float
    batch: int
    batch_ms_per_frame: float | None
    clients: int
    client_phrases: int
    served_ms_per_frame: float | None
    served_overhead_ms: float | None
    served_stages_ms: dict[str, float] | None
    served_added_ms: float | None
    served_mean_batch: float | None
    client_encode_ms: float | None
    client_decode_ms: float | None
    gpu_memory_mb: float | None
    notes: str


@dataclass(frozen=True)
class _FrameTiming:
    preprocess: float
    forward: float
    postprocess: float
    segment: float
    boxes: int
    detections: int

    @property
    def total(self) -> float:
        return self.preprocess + self.forward + self.postprocess


def bench_grounder(options: GrounderBenchOptions) -> GrounderBenchResult:
    """Build the grounder, warm it up, time ``options.frames`` frames one at a time (and batched when asked)."""
    import torch

    _check(options)
    device = pick_device(options.device)
    on_cuda = device.startswith("cuda")
    if on_cuda and not torch.cuda.is_available():
        raise InputError("command line", "--device", "cpu, or cuda where a GPU is visible", device)
    if on_cuda:
        torch.cuda.reset_peak_memory_stats()
    grounder, model = bench_model(options, device)
    timed = None
    if isinstance(grounder, BoxGrounder):
        timed = grounder.segmenter = _TimedSegmenter(grounder.segmenter, device)
    frames = _frames(WARMUP_FRAMES + options.frames)
    for rgb in frames[:WARMUP_FRAMES]:
        _time_frame(grounder, rgb, device, timed)
    timings = [_time_frame(grounder, rgb, device, timed) for rgb in frames[WARMUP_FRAMES:]]
    totals = [t.total for t in timings]
    dtype = str(resolve_dtype(options.dtype, device)).removeprefix("torch.")
    served = _served(grounder, options, device) if options.clients else None
    return GrounderBenchResult(
        detector=options.detector,
        model=model,
        device=device,
        dtype=dtype,
        image_processor=getattr(grounder.processor.image_processor, "backend", "unknown"),
        frames=options.frames,
        frame=f"{FRAME_WIDTH}x{FRAME_HEIGHT}",
        median_ms=_ms(np.median(totals)),
        p90_ms=_ms(np.percentile(totals, 90)),
        preprocess_ms=_ms(np.median([t.preprocess for t in timings])),
        forward_ms=_ms(np.median([t.forward for t in timings])),
        postprocess_ms=_ms(np.median([t.postprocess for t in timings])),
        segment_ms=_ms(np.median([t.segment for t in timings])) if timed is not None else None,
        detections_per_frame=float(np.median([t.detections for t in timings])),
        batch=options.batch,
        batch_ms_per_frame=_batched(grounder, options, device) if options.batch > 1 else None,
        clients=options.clients,
        client_phrases=options.phrases,
        served_ms_per_frame=served.ms_per_frame if served else None,
        served_overhead_ms=served.overhead_ms if served else None,
        served_stages_ms=served.times.per_frame_ms() if served else None,
        served_added_ms=served.times.added_ms() if served else None,
        served_mean_batch=round(served.times.frames / served.times.batches, 2) if served else None,
        client_encode_ms=served.encode_ms if served else None,
        client_decode_ms=served.decode_ms if served else None,
        gpu_memory_mb=round(torch.cuda.max_memory_allocated() / 2**20, 1) if on_cuda else None,
        notes=_notes(options, on_cuda and dtype == "float32", timings if timed is not None else None),
    )


def _notes(options: GrounderBenchOptions, tf32: bool, segmented: list[_FrameTiming] | None) -> str:
    """What the figures were measured with, beyond the result's fields."""
    notes = ["text features encoded once (cached per episode)"]
    if segmented is not None:
        weights = options.segmenter_checkpoint or ("tiny random weights" if options.tiny else "random weights")
        described = options.segmenter if options.segmenter == DEFAULT_SEGMENTER else f"{options.segmenter} ({weights})"
        boxes = np.median([t.boxes for t in segmented])
        notes.append(f"boxes to masks: {described}, a median of {boxes:g} boxes a frame")
    if options.compile:
        notes.append(f"torch.compile ({COMPILE_BACKEND}) of the per-frame modules, compiled in the untimed frames")
    if tf32:
        notes.append("TF32 matmuls (fp32 on CUDA)")
    return "; ".join([*notes, SERVED_NOTE])


class _TimedSegmenter:
    """A box segmenter timing each call of ``inner`` (``seconds``) and counting its boxes."""

    def __init__(self, inner: BoxSegmenter, device: str) -> None:
        self.inner = inner
        self.device = device
        self.seconds = 0.0
        self.boxes = 0

    def segment_boxes(self, rgb: NDArray[np.uint8], boxes: NDArray[np.float32]) -> NDArray[np.bool_]:
        result = _timed(lambda: self.inner.segment_boxes(rgb, boxes), self.device)
        masks: NDArray[np.bool_] = result[0]
        self.seconds += result[1]
        self.boxes += len(boxes)
        return masks


def bench_model(options: GrounderBenchOptions, device: str) -> tuple[TransformersGrounder, str]:
    """The grounder and a description of its model: the checkpoint's, else random weights (tiny or full size); a box
    detector's segmenter from its checkpoint, else with random weights."""
    from drivenav.semantics.random_grounders import GROUNDERS, random_grounder, random_segmenter

    spec = options.spec(device)
    options_of: dict[str, Any] = {"dtype": spec.dtype, "compile_backend": compile_backend_for(spec.compile)}
    if spec.detector in BOX_DETECTORS:
        random = options.tiny or not options.segmenter_checkpoint
        options_of["segmenter"] = random_segmenter(spec, options.tiny) if random else make_segmenter(spec)
    kind = GROUNDERS[spec.detector]
    if options.checkpoint:
        return kind(options.checkpoint, device, **options_of), options.checkpoint
    if not (options.random_weights or options.tiny):
        try:
            return kind(device=device, **options_of), "the default checkpoint (from the Hugging Face cache)"
        except InputError:  # not in the cache: random weights time the same
            pass
    grounder = random_grounder(spec, options.tiny, options_of.get("segmenter"))
    described = "tiny test configuration" if options.tiny else "full-size default configuration"
    return grounder, f"{described}, random weights"


def _frames(count: int) -> list[NDArray[np.uint8]]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (FRAME_HEIGHT, FRAME_WIDTH, 3), dtype=np.uint8) for _ in range(count)]


def _time_frame(
    grounder: TransformersGrounder, rgb: NDArray[np.uint8], device: str, segmenter: _TimedSegmenter | None
) -> _FrameTiming:
    """One frame through the grounder's stages, as :meth:`~TransformersGrounder.segment` runs them (``segmenter``:
    the grounder's timed box segmenter, if it has one)."""
    import torch

    seconds, boxes = (segmenter.seconds, segmenter.boxes) if segmenter is not None else (0.0, 0)
    with torch.inference_mode():
        text = grounder.text_features(PHRASE)
        pixels, preprocess = _timed(lambda: grounder.preprocess([rgb]), device)
        outputs, forward = _timed(lambda: grounder.decode_rows(grounder.encode_vision(pixels), [text]), device)
        detections, postprocess = _timed(lambda: grounder.postprocess(outputs, [rgb], [PHRASE]), device)
    found = len(detections[0])
    if segmenter is None:
        return _FrameTiming(preprocess, forward, postprocess, 0.0, 0, found)
    segment = segmenter.seconds - seconds
    return _FrameTiming(preprocess, forward, postprocess, segment, segmenter.boxes - boxes, found)


def _batched(grounder: TransformersGrounder, options: GrounderBenchOptions, device: str) -> float:
    """Milliseconds per frame of :meth:`~TransformersGrounder.segment_batch` on ``options.batch`` frames (the
    median of ``max(1, frames // batch)`` batches after one untimed batch)."""
    frames = _frames(options.batch)
    repeats = max(1, options.frames // options.batch)
    seconds = [_timed(lambda: grounder.segment_batch(frames, PHRASE), device)[1] for _ in range(repeats + 1)]
    return _ms(np.median(seconds[1:]) / options.batch)


@dataclass(frozen=True)
class _Served:
    ms_per_frame: float
    overhead_ms: float
    times: ServerTimes
    encode_ms: float
    decode_ms: float


def _served(grounder: TransformersGrounder, options: GrounderBenchOptions, device: str) -> _Served:
    """The served path's throughput with ``options.clients`` clients and its batch-1 overhead (module docstring)."""
    from drivenav.semantics.grounder_server import GrounderServer, serving
    from drivenav.semantics.serve_config import MAX_BATCH, ServeConfig
    from drivenav.semantics.served import ServedInfo

    def server(config: ServeConfig) -> GrounderServer:
        info = ServedInfo(options.detector, "bench", device, "bench", ("rgb",), False, config.batch, config.batch_ms)
        return GrounderServer(lambda: grounder, info, "tcp://127.0.0.1:*", None, config)

    frames = _frames(OVERHEAD_FRAMES + options.frames)
    local = [_timed(partial(grounder.segment_batch, [rgb], PHRASE), device)[1] for rgb in frames]
    with serving(server(ServeConfig(batch=1, batch_ms=0.0))) as endpoint:
        remote = [_served_seconds(endpoint, frames)[OVERHEAD_FRAMES:]]
    overhead = np.median(remote[0]) - np.median(local[OVERHEAD_FRAMES:])
    concurrent = server(ServeConfig(batch=min(options.clients, MAX_BATCH)))
    with serving(concurrent) as endpoint:
        wall = _concurrent_seconds(endpoint, frames, options.clients, CLIENT_PHRASES[: options.phrases])
    encode_ms, decode_ms = _client_codec_ms(grounder, frames[-1])
    per_frame = _ms(wall / (options.clients * options.frames))
    return _Served(per_frame, _ms(overhead), concurrent.times, encode_ms, decode_ms)


def _client_codec_ms(grounder: TransformersGrounder, rgb: NDArray[np.uint8]) -> tuple[float, float]:
    """A client's median milliseconds to make and encode a SEGMENT of ``rgb``, and to decode the DETECTIONS of its
    detections (masks unpacked), over :data:`CODEC_REPEATS` repeats."""
    from drivenav.semantics.served import (
        GROUNDER_PROTOCOL,
        REPLIES,
        detections_reply,
        read_detections,
        segment_request,
    )
    from drivenav.wire.protocol import decode, encode

    observation = _observation(rgb, 0)
    size = (FRAME_HEIGHT, FRAME_WIDTH)
    reply = encode(detections_reply("1", PHRASE, grounder.segment_batch([rgb], PHRASE)[0], size), GROUNDER_PROTOCOL)

    def request() -> object:
        return encode(segment_request("1", "e", observation, PHRASE, ("rgb",)), GROUNDER_PROTOCOL)

    def detections() -> object:
        message = decode([memoryview(frame) for frame in reply], REPLIES, GROUNDER_PROTOCOL)
        return read_detections(message, PHRASE, size)

    timed = [[_timed(work, "cpu")[1] for _ in range(CODEC_REPEATS)] for work in (request, detections)]
    return _ms(np.median(timed[0])), _ms(np.median(timed[1]))


def _served_seconds(
    endpoint: str, frames: list[NDArray[np.uint8]], ready: threading.Barrier | None = None, phrase: str = PHRASE
) -> list[float]:
    """Each frame's seconds through a served grounder at ``endpoint``, one after another (after ``ready``), looking
    for ``phrase``."""
    from drivenav.semantics.remote import RemoteGrounder
    from drivenav.semantics.served import GrounderClient, ServedInfo

    client = GrounderClient(endpoint)
    try:
        info = ServedInfo.from_json(client.request(Message("HELLO", client.next_id())).body)
        grounder = RemoteGrounder(client, info)
        grounder.begin_episode(None, 0)
        if ready is not None:
            ready.wait()
        observations = [_observation(rgb, step) for step, rgb in enumerate(frames)]
        return [_timed(partial(grounder.segment, frame, phrase), "cpu")[1] for frame in observations]
    finally:
        client.close()


def _concurrent_seconds(endpoint: str, frames: list[NDArray[np.uint8]], clients: int, phrases: Sequence[str]) -> float:
    """Wall seconds for ``clients`` threads each grounding ``frames`` (after the first :data:`OVERHEAD_FRAMES`)
    through the server at ``endpoint``, all started together, client ``i`` looking for ``phrases[i mod len]``."""
    ready = threading.Barrier(clients + 1)
    threads = [
        threading.Thread(
            target=_served_seconds, args=(endpoint, frames[OVERHEAD_FRAMES:], ready, phrases[i % len(phrases)])
        )
        for i in range(clients)
    ]
    for thread in threads:
        thread.start()
    ready.wait()
    start = time.perf_counter()
    for thread in threads:
        thread.join()
    return time.perf_counter() - start


def _observation(rgb: NDArray[np.uint8], step: int) -> Observation:
    """A bench frame as an observation (the served grounder reads its RGB image only)."""
    return Observation(
        rgb=rgb,
        depth=np.zeros(rgb.shape[:2], dtype=np.float32),
        semantic=None,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(FRAME_WIDTH, FRAME_HEIGHT, BENCH_HFOV_DEG),
        step=step,
        collided=False,
    )


def _timed(work: Callable[[], Any], device: str) -> tuple[Any, float]:
    """``work()`` and the seconds it took (on CUDA, until the device is done)."""
    start = time.perf_counter()
    result = work()
    _synchronize(device)
    return result, time.perf_counter() - start


def _synchronize(device: str) -> None:
    if device.startswith("cuda"):
        import torch

        torch.cuda.synchronize()


def _ms(seconds: float | np.floating[Any]) -> float:
    return round(float(seconds) * 1000.0, 3)


def _check(options: GrounderBenchOptions) -> None:
    """The choices that argparse cannot check, one InputError each: a checkpoint goes without ``--random-weights``
    and ``--tiny``; the clients' objects are 1 to :data:`CLIENT_PHRASES`' many, more than one only with clients; a
    segmenter other than the default goes with a box detector only."""
    for option, checkpoint in (
        (DETECTOR_OPTION, options.checkpoint),
        ("--segmenter-model", options.segmenter_checkpoint),
    ):
        if checkpoint and (options.random_weights or options.tiny):
            raise InputError("command line", option, "no checkpoint with --random-weights or --tiny", checkpoint)
    if not 1 <= options.phrases <= len(CLIENT_PHRASES) or (options.phrases > 1 and not options.clients):
        expected = f"1 to {len(CLIENT_PHRASES)} different objects, more than 1 only with --clients"
        raise InputError("command line", "--phrases", expected, str(options.phrases))
    if options.segmenter != DEFAULT_SEGMENTER and options.detector not in BOX_DETECTORS:
        expected = f"{DEFAULT_SEGMENTER} with --detector {options.detector} (it makes its own masks)"
        raise InputError("command line", "--segmenter", expected, options.segmenter)
