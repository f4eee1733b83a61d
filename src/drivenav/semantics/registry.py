"""Reasoner and grounder backends by command-line name (``--reasoner``, ``--detector``).

Backends are built lazily (heavy imports only when chosen) from a picklable :class:`ModelSpec`, so worker
processes build their own.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.errors import InputError

if TYPE_CHECKING:  # the command line reads the names here without loading numpy
    from drivenav.semantics.protocols import Grounder, Reasoner

REASONERS = ("embedded", "openai", "replay", "geometric")
DETECTORS = ("embedded", "ground-truth", "sam3", "owlv2")
_STAND_INS = {"embedded", "ground-truth"}  # read the world's instance labels: ground truth (``semantic``)


@dataclass(frozen=True)
class ModelSpec:
    """Which models an agent uses and how to reach them."""

    reasoner: str = "embedded"
    detector: str = "embedded"
    vlm_base_url: str = "http://127.0.0.1:8000/v1"
    vlm_model: str = "Qwen/Qwen3-VL-8B-Instruct"
    vlm_record: str = ""
    vlm_replay: str = ""
    detector_model: str = ""


def model_requirements(spec: ModelSpec) -> frozenset[str]:
    """The privileged inputs the chosen models need: the embedded stand-ins read ground-truth labels."""
    from drivenav.types import SEMANTIC

    return frozenset({SEMANTIC}) if {spec.reasoner, spec.detector} & _STAND_INS else frozenset()


def make_reasoner(spec: ModelSpec) -> Reasoner:
    """The reasoner named by ``spec`` (wrapped in a recorder when ``vlm_record`` is set)."""
    reasoner = _base_reasoner(spec)
    if spec.vlm_record:
        from drivenav.semantics.replay import RecordingReasoner

        reasoner = RecordingReasoner(reasoner, Path(spec.vlm_record))
    return reasoner


def _base_reasoner(spec: ModelSpec) -> Reasoner:
    if spec.reasoner == "embedded":
        from drivenav.semantics.embedded import EmbeddedReasoner

        return EmbeddedReasoner()
    if spec.reasoner == "openai":
        from drivenav.semantics.openai_backend import OpenAIReasoner

        return OpenAIReasoner(spec.vlm_base_url, spec.vlm_model)
    if spec.reasoner == "replay":
        from drivenav.semantics.replay import ReplayReasoner

        return ReplayReasoner(Path(spec.vlm_replay))
    if spec.reasoner == "geometric":
        from drivenav.semantics.geometric import GeometricReasoner

        return GeometricReasoner()
    raise InputError("command line", "--reasoner", f"one of {', '.join(REASONERS)}", spec.reasoner)


def make_grounder(spec: ModelSpec) -> Grounder:
    """The grounder named by ``spec``."""
    if spec.detector == "embedded":
        from drivenav.semantics.embedded_detector import EmbeddedGrounder

        return EmbeddedGrounder()
    if spec.detector == "ground-truth":
        from drivenav.semantics.ground_truth import GroundTruthGrounder

        return GroundTruthGrounder()
    if spec.detector in ("sam3", "owlv2"):
        return _hf_grounder(spec)
    raise InputError("command line", "--detector", f"one of {', '.join(DETECTORS)}", spec.detector)


def _hf_grounder(spec: ModelSpec) -> Grounder:
    """SAM3 or OWLv2 through transformers; without the ``models`` extra, one line naming it."""
    try:
        if spec.detector == "sam3":
            from drivenav.semantics.sam3_grounder import Sam3Grounder

            return Sam3Grounder(spec.detector_model or "facebook/sam3")
        from drivenav.semantics.owlv2_grounder import Owlv2Grounder

        return Owlv2Grounder(spec.detector_model or "google/owlv2-base-patch16-ensemble")
    except ImportError as error:
        raise InputError(
            "command line",
            "--detector",
            f"the models extra for {spec.detector} (pip install 'drivenav[models]')",
            _import_problem(error),
        ) from None


def _import_problem(error: ImportError) -> str:
    """What failed to import: a missing package by name, else the first line of the error (an outdated package)."""
    if isinstance(error, ModuleNotFoundError):
        return f"{error.name or 'a dependency'} not installed"
    return str(error).splitlines()[0]


def _check_record_path(path: Path) -> None:
    """``--vlm-record`` names a file this process can append to (not a directory, in a writable folder)."""
    if path.is_dir():
        raise InputError(path, "--vlm-record", "a file to append the reasoner's records to", "a directory")
    try:
        with path.open("a", encoding="utf-8"):
            pass
    except OSError as error:
        raise InputError(path, "--vlm-record", "a writable file path", error.strerror or str(error)) from None


def check_models(spec: ModelSpec) -> None:
    """Fail fast, before any episode: unknown names, an unreachable VLM server, a missing replay file."""
    if spec.reasoner not in REASONERS:
        raise InputError("command line", "--reasoner", f"one of {', '.join(REASONERS)}", spec.reasoner)
    if spec.detector not in DETECTORS:
        raise InputError("command line", "--detector", f"one of {', '.join(DETECTORS)}", spec.detector)
    if spec.reasoner == "replay" and not Path(spec.vlm_replay).is_file():
        raise InputError(spec.vlm_replay or "command line", "--vlm-replay", "a file written with --vlm-record")
    if spec.reasoner == "replay":
        make_reasoner(spec)  # reads the recording now: a malformed one fails before any episode
    if spec.vlm_record:
        _check_record_path(Path(spec.vlm_record))
    if spec.reasoner == "openai":
        from drivenav.semantics.openai_backend import OpenAIReasoner

        OpenAIReasoner(spec.vlm_base_url, spec.vlm_model).check_connection()
    if spec.detector in ("sam3", "owlv2"):
        make_grounder(spec)  # loads the weights now: a missing checkpoint fails before any episode
