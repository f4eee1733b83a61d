"""Which models an agent uses and how to reach them (the settings' ``models`` section): a picklable spec, so that
worker processes build their own models from it (:mod:`drivenav.semantics.registry`)."""

from __future__ import annotations

from dataclasses import dataclass

from drivenav.ranges import Range, check_ranges
from drivenav.semantics.serve_config import DEFAULT_BIND, DEFAULT_MAX_DETECTIONS, MAX_DETECTIONS


@dataclass(frozen=True)
class ModelSpec:
    """Which models an agent uses and how to reach them.

    ``detector_model`` / ``scorer_model``: the grounder's / scorer's checkpoint (empty: the backend's default).
    ``vlm_record`` / ``vlm_replay``: the one file that records / replays both the reasoner's and the scorer's
    answers. ``dtype``: the grounder's weights and inputs, one of :data:`DTYPES` (``auto``: bf16 on a CUDA device
    that supports it, fp32 elsewhere); ``detector_device``: where a transformers grounder runs (empty: CUDA when
    visible, else the CPU). ``detector_url`` / ``detector_keys``: with ``detector`` ``remote``, the served
    grounder's endpoint (``drivenav serve grounder``) and the CURVE key folder when it is not on loopback;
    ``detector_timeout_s``: how long after its sending a request may wait for its reply before its episode ends as
    an error (long enough for a batch of full-size forwards on a CPU; more than 0, at most an hour);
    ``detector_served``: the detector the server runs, when the workers must know it (set by ``eval
    --share-detector``; required for a served stand-in that reads ground-truth labels, whose agents then ask the
    world for them; empty: a model that reads images). ``segmenter`` / ``segmenter_model``: what turns a box
    detector's boxes into masks (``--segmenter``: the filled box, or MobileSAM from its checkpoint file). ``compile``:
    ``torch.compile`` of the models' per-frame modules. ``detector_shadow_url``: a served grounder sent every frame
    the detector grounds, its answer discarded (a served model's cost beside the detector's detections: throughput
    benchmarks with random weights). ``detector_regime``: with ``detector`` ``embedded``, which of its presets
    (:data:`DETECTOR_REGIMES`; docs/regimes.md) it runs: ``paper`` (the default), ``exact``, ``strong``, ``weak``.
    ``max_detections``: the most detections a frame the agent takes from its grounder, the best scores (each costs
    a pass over the frame; :data:`~drivenav.semantics.serve_config.DEFAULT_MAX_DETECTIONS`, more than any
    built-in grounder returns; :mod:`drivenav.semantics.checked`).
    """

    reasoner: str = "embedded"
    detector: str = "embedded"
    vlm_base_url: str = "http://127.0.0.1:8000/v1"
    vlm_model: str = "Qwen/Qwen3-VL-8B-Instruct"
    vlm_record: str = ""
    vlm_replay: str = ""
    detector_model: str = ""
    scorer: str = "embedded"
    scorer_model: str = ""
    dtype: str = "auto"
    detector_device: str = ""
    detector_url: str = DEFAULT_BIND
    detector_keys: str = ""
    detector_timeout_s: float = 60.0
    detector_served: str = ""
    segmenter: str = "filled-box"
    segmenter_model: str = ""
    compile: bool = False
    detector_shadow_url: str = ""
    detector_regime: str = "paper"
    max_detections: int = DEFAULT_MAX_DETECTIONS

    def __post_init__(self) -> None:
        check_ranges(
            self,
            {
                "detector_timeout_s": Range(0.0, 3600.0, low_open=True, why="seconds, up to an hour"),
                "max_detections": Range(1, MAX_DETECTIONS, integer=True, why="detections a frame"),
            },
        )


DTYPES = ("auto", "float32", "bfloat16", "float16")
"""The values of ``models.dtype`` (``--dtype``)."""

DETECTOR_REGIMES = ("exact", "strong", "paper", "weak")
"""The embedded detector's presets (``models.detector_regime``, ``--detector-regime``;
:func:`drivenav.semantics.embedded_detector.regime_grounder`): the ground-truth grounder, a SAM3-class model, the
embedded benchmark's own detector, an OWLv2-class model."""
