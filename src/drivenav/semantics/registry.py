"""Reasoner, grounder, box segmenter and scorer backends by command-line name (``--reasoner``, ``--detector``,
``--segmenter``, ``--scorer``).

Each role (the VLM's reasoning of Sec. IV-B/IV-C, the segmenter's grounding, the masks of a box detector's boxes, the
VLFM baseline's image-text scoring) has one :class:`ModelRegistry`, an entry-point group of its own
(``drivenav.reasoners``, ``drivenav.grounders``, ``drivenav.segmenters``, ``drivenav.scorers``;
:mod:`drivenav.plugins`): a name maps to a :class:`Backend`, which builds the model from a picklable
:class:`ModelSpec` (so that worker processes build their own) and says what the model needs. Backends import their
heavy modules only when built, and the names are listed without loading any backend, so the command line reads them
without loading numpy. A new backend is one ``Backend`` object and one entry point (drivenav's own: one line in a
``BUILT_IN_*`` table below and in pyproject.toml); a new role is one more registry and group.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from drivenav.errors import InputError
from drivenav.plugins import Registry
from drivenav.semantics.model_spec import ModelSpec

if TYPE_CHECKING:  # the command line reads the names here without loading numpy
    from drivenav.semantics.boxes import BoxSegmenter
    from drivenav.semantics.protocols import Grounder, ImageTextScorer, Reasoner

Model = TypeVar("Model")


BOX_DETECTORS = ("owlv2", "grounding-dino")
"""The detectors that give boxes, turned into masks by ``--segmenter``; the others make their own masks."""
MODEL_DETECTORS = ("sam3", *BOX_DETECTORS)
"""The detectors run by transformers models (weights to load, ``--dtype`` and ``--compile`` apply)."""
MOBILESAM_EXPECTED = "a MobileSAM checkpoint file (mobile_sam.pt)"


def _no_check(spec: ModelSpec) -> None:
    """A backend with nothing to check before a run."""


@dataclass(frozen=True)
class Backend(Generic[Model]):
    """One named model of a role.

    ``build`` makes it from a :class:`ModelSpec` (importing its module then). ``reads_labels``: it reads the
    world's ground-truth instance labels (the embedded stand-ins), so agents using it need ``semantic``.
    ``observes``: the images of an observation it reads (what a served grounder's clients send it).
    ``reads_geodesic``: it reads the episode's geodesic distance to the goals (the oracle), so agents using it need
    ``geodesic``. ``takes_regime``: a grounder with presets that ``models.detector_regime`` chooses (the embedded
    detector). ``check`` runs cheap local checks before any episode (a file to read); ``connect`` the costly ones
    (a server to reach, weights to load), which run after every cheap check so that a typo fails at once.
    """

    build: Callable[[ModelSpec], Model]
    reads_labels: bool = False
    reads_geodesic: bool = False
    takes_regime: bool = False
    check: Callable[[ModelSpec], None] = _no_check
    connect: Callable[[ModelSpec], None] = _no_check
    observes: tuple[str, ...] = ("rgb",)


class ModelRegistry(Registry[Backend[Model]]):
    """The backends of one role by name: drivenav's own in the order of ``built_ins`` (the order ``--help`` lists
    them), then other packages' (entry-point ``group``); ``option`` is the command-line option that names one."""

    def __init__(self, group: str, built_ins: Mapping[str, str], option: str) -> None:
        super().__init__(group, built_ins, _is_backend, "model backend (drivenav.semantics.registry.Backend)", option)

    def reads_labels(self, name: str) -> bool:
        """Whether ``name`` reads ground-truth labels (False for an unknown name: it is refused elsewhere)."""
        return name in self.declared and self.get(name).reads_labels

    def reads_geodesic(self, name: str) -> bool:
        """Whether ``name`` reads the geodesic distance to the goals (False for an unknown name)."""
        return name in self.declared and self.get(name).reads_geodesic


def _is_backend(part: object) -> bool:
    return isinstance(part, Backend)


def _embedded_reasoner(spec: ModelSpec) -> Reasoner:
    from drivenav.semantics.embedded import EmbeddedReasoner

    return EmbeddedReasoner()


def _openai_reasoner(spec: ModelSpec) -> Reasoner:
    from drivenav.semantics.openai_backend import OpenAIReasoner

    return OpenAIReasoner(spec.vlm_base_url, spec.vlm_model)


def _reach_vlm(spec: ModelSpec) -> None:
    """The OpenAI-compatible server answers (before any episode, not at the first decision)."""
    from drivenav.semantics.openai_backend import OpenAIReasoner

    OpenAIReasoner(spec.vlm_base_url, spec.vlm_model).check_connection()


def _replay_reasoner(spec: ModelSpec) -> Reasoner:
    from drivenav.semantics.replay import ReplayReasoner

    return ReplayReasoner(Path(spec.vlm_replay))


def _read_recording(spec: ModelSpec) -> None:
    """The recording exists and reads: a missing or malformed one fails before any episode."""
    if not Path(spec.vlm_replay).is_file():
        raise InputError(spec.vlm_replay or "command line", "--vlm-replay", "a file written with --vlm-record")
    from drivenav.semantics.replay import Recording

    Recording(Path(spec.vlm_replay))


def _geometric_reasoner(spec: ModelSpec) -> Reasoner:
    from drivenav.semantics.geometric import GeometricReasoner

    return GeometricReasoner()


def _oracle_reasoner(spec: ModelSpec) -> Reasoner:
    from drivenav.semantics.oracle import OracleReasoner

    return OracleReasoner()


def _embedded_grounder(spec: ModelSpec) -> Grounder:
    from drivenav.semantics.embedded_detector import regime_grounder

    return regime_grounder(spec.detector_regime)


def _ground_truth_grounder(spec: ModelSpec) -> Grounder:
    from drivenav.semantics.ground_truth import GroundTruthGrounder

    return GroundTruthGrounder()


def _sam3_grounder(spec: ModelSpec) -> Grounder:
    try:
        from drivenav.semantics.sam3_grounder import Sam3Grounder

        return _placed(Sam3Grounder, spec)(spec.detector_model or "facebook/sam3", **_model_options(spec))
    except ImportError as error:
        raise _models_extra_missing("--detector", spec.detector, error) from None


def _owlv2_grounder(spec: ModelSpec) -> Grounder:
    try:
        from drivenav.semantics.owlv2_grounder import Owlv2Grounder

        owlv2 = _placed(Owlv2Grounder, spec)
        model = spec.detector_model or "google/owlv2-base-patch16-ensemble"
        return owlv2(model, segmenter=make_segmenter(spec), **_model_options(spec))
    except ImportError as error:
        raise _models_extra_missing("--detector", spec.detector, error) from None


def _grounding_dino_grounder(spec: ModelSpec) -> Grounder:
    try:
        from drivenav.semantics.grounding_dino_grounder import GROUNDING_DINO_CHECKPOINT, GroundingDinoGrounder

        grounding_dino = _placed(GroundingDinoGrounder, spec)
        model = spec.detector_model or GROUNDING_DINO_CHECKPOINT
        return grounding_dino(model, segmenter=make_segmenter(spec), **_model_options(spec))
    except ImportError as error:
        raise _models_extra_missing("--detector", spec.detector, error) from None


def _model_options(spec: ModelSpec) -> dict[str, str]:
    """A transformers model's dtype and compile backend (``models.dtype``, ``models.compile``)."""
    from drivenav.semantics.hf_common import compile_backend_for

    return {"dtype": spec.dtype, "compile_backend": compile_backend_for(spec.compile)}


def _placed(kind: Callable[..., Model], spec: ModelSpec) -> Callable[..., Model]:
    """A transformers grounder's constructor given ``detector_device`` when set (else the grounder's choice)."""
    return partial(kind, device=spec.detector_device) if spec.detector_device else kind


def _remote_grounder(spec: ModelSpec) -> Grounder:
    from drivenav.semantics.remote import remote_grounder

    return remote_grounder(spec)


def _check_detector_url(spec: ModelSpec) -> None:
    """``detector_url`` is a ``tcp://HOST:PORT`` (or ``ipc://``) endpoint, with keys off loopback."""
    from drivenav.semantics.remote import check_detector_url

    check_detector_url(spec)


def _reach_grounder(spec: ModelSpec) -> None:
    """The served grounder answers HELLO (before any episode)."""
    from drivenav.semantics.remote import reach_server

    reach_server(spec)


def _load_weights(spec: ModelSpec) -> None:
    """Loads the segmenter's weights now: a missing checkpoint fails before any episode."""
    make_grounder(spec)


def _models_extra_missing(option: str, name: str, error: ImportError) -> InputError:
    """A torch backend (SAM3, OWLv2, Grounding DINO, MobileSAM, BLIP-2, SigLIP) without the ``models`` extra: one
    line naming it."""
    return InputError(
        "command line",
        option,
        f"the models extra for {name} (pip install 'drivenav[models]')",
        _import_problem(error),
    )


def _import_problem(error: ImportError) -> str:
    """What failed to import: a missing package by name, else the first line of the error (an outdated package)."""
    if isinstance(error, ModuleNotFoundError):
        return f"{error.name or 'a dependency'} not installed"
    return str(error).splitlines()[0]


EMBEDDED_REASONER: Backend[Reasoner] = Backend(_embedded_reasoner, reads_labels=True)
OPENAI_REASONER: Backend[Reasoner] = Backend(_openai_reasoner, connect=_reach_vlm)
REPLAY_REASONER: Backend[Reasoner] = Backend(_replay_reasoner, check=_read_recording)
GEOMETRIC_REASONER: Backend[Reasoner] = Backend(_geometric_reasoner)
ORACLE_REASONER: Backend[Reasoner] = Backend(_oracle_reasoner, reads_labels=True, reads_geodesic=True)

BUILT_IN_REASONERS = {
    "embedded": "drivenav.semantics.registry:EMBEDDED_REASONER",
    "openai": "drivenav.semantics.registry:OPENAI_REASONER",
    "replay": "drivenav.semantics.registry:REPLAY_REASONER",
    "geometric": "drivenav.semantics.registry:GEOMETRIC_REASONER",
    "oracle": "drivenav.semantics.registry:ORACLE_REASONER",
}
"""drivenav's own reasoners (``--reasoner``; also declared in pyproject.toml, group ``drivenav.reasoners``)."""

REASONER_BACKENDS: ModelRegistry[Reasoner] = ModelRegistry("drivenav.reasoners", BUILT_IN_REASONERS, "--reasoner")

EMBEDDED_GROUNDER: Backend[Grounder] = Backend(
    _embedded_grounder, reads_labels=True, takes_regime=True, observes=("depth", "semantic")
)
GROUND_TRUTH_GROUNDER: Backend[Grounder] = Backend(_ground_truth_grounder, reads_labels=True, observes=("semantic",))
SAM3_GROUNDER: Backend[Grounder] = Backend(_sam3_grounder, connect=_load_weights)
OWLV2_GROUNDER: Backend[Grounder] = Backend(_owlv2_grounder, connect=_load_weights)
GROUNDING_DINO_GROUNDER: Backend[Grounder] = Backend(_grounding_dino_grounder, connect=_load_weights)
REMOTE_GROUNDER: Backend[Grounder] = Backend(_remote_grounder, check=_check_detector_url, connect=_reach_grounder)

BUILT_IN_GROUNDERS = {
    "embedded": "drivenav.semantics.registry:EMBEDDED_GROUNDER",
    "ground-truth": "drivenav.semantics.registry:GROUND_TRUTH_GROUNDER",
    "sam3": "drivenav.semantics.registry:SAM3_GROUNDER",
    "owlv2": "drivenav.semantics.registry:OWLV2_GROUNDER",
    "grounding-dino": "drivenav.semantics.registry:GROUNDING_DINO_GROUNDER",
    "remote": "drivenav.semantics.registry:REMOTE_GROUNDER",
}
"""drivenav's own grounders (``--detector``; also declared in pyproject.toml, group ``drivenav.grounders``)."""

GROUNDER_BACKENDS: ModelRegistry[Grounder] = ModelRegistry("drivenav.grounders", BUILT_IN_GROUNDERS, "--detector")


def _filled_box_segmenter(spec: ModelSpec) -> BoxSegmenter:
    from drivenav.semantics.boxes import FilledBoxSegmenter

    return FilledBoxSegmenter()


def _mobilesam_segmenter(spec: ModelSpec) -> BoxSegmenter:
    try:
        from drivenav.semantics.hf_common import compile_backend_for
        from drivenav.semantics.mobilesam_segmenter import MobileSamSegmenter, load_checkpoint

        model = load_checkpoint(Path(spec.segmenter_model))
        device = spec.detector_device or None
        return MobileSamSegmenter(model, device, spec.dtype, compile_backend_for(spec.compile))
    except ImportError as error:
        raise _models_extra_missing("--segmenter", spec.segmenter, error) from None


def _check_segmenter_file(spec: ModelSpec) -> None:
    """MobileSAM's checkpoint is a file (read when the detector loads)."""
    if not Path(spec.segmenter_model).is_file():
        raise InputError("command line", "--segmenter-model", MOBILESAM_EXPECTED, spec.segmenter_model or "(none)")


FILLED_BOX_SEGMENTER: Backend[BoxSegmenter] = Backend(_filled_box_segmenter)
MOBILESAM_SEGMENTER: Backend[BoxSegmenter] = Backend(_mobilesam_segmenter, check=_check_segmenter_file)

BUILT_IN_SEGMENTERS = {
    "filled-box": "drivenav.semantics.registry:FILLED_BOX_SEGMENTER",
    "mobilesam": "drivenav.semantics.registry:MOBILESAM_SEGMENTER",
}
"""drivenav's own box segmenters (``--segmenter``; also declared in pyproject.toml, group ``drivenav.segmenters``)."""

SEGMENTER_BACKENDS: ModelRegistry[BoxSegmenter] = ModelRegistry(
    "drivenav.segmenters", BUILT_IN_SEGMENTERS, "--segmenter"
)


def _embedded_scorer(spec: ModelSpec) -> ImageTextScorer:
    from drivenav.semantics.embedded_scorer import EmbeddedScorer

    return EmbeddedScorer()


def _blip2_scorer(spec: ModelSpec) -> ImageTextScorer:
    try:
        from drivenav.semantics.itm_scorer import BLIP2_ITM_CHECKPOINT, Blip2ItmScorer

        return Blip2ItmScorer(spec.scorer_model or BLIP2_ITM_CHECKPOINT)
    except ImportError as error:
        raise _models_extra_missing("--scorer", spec.scorer, error) from None


def _siglip_scorer(spec: ModelSpec) -> ImageTextScorer:
    try:
        from drivenav.semantics.itm_scorer import SIGLIP_CHECKPOINT, SiglipScorer

        return SiglipScorer(spec.scorer_model or SIGLIP_CHECKPOINT)
    except ImportError as error:
        raise _models_extra_missing("--scorer", spec.scorer, error) from None


def _load_scorer_weights(spec: ModelSpec) -> None:
    """Loads the scorer's weights now: a missing checkpoint fails before any episode."""
    SCORER_BACKENDS.get(spec.scorer).build(spec)


def _oracle_scorer(spec: ModelSpec) -> ImageTextScorer:
    from drivenav.semantics.oracle import OracleScorer

    return OracleScorer()


def _replay_scorer(spec: ModelSpec) -> ImageTextScorer:
    from drivenav.semantics.replay import ReplayScorer

    return ReplayScorer(Path(spec.vlm_replay))


EMBEDDED_SCORER: Backend[ImageTextScorer] = Backend(_embedded_scorer, reads_labels=True)
BLIP2_ITM_SCORER: Backend[ImageTextScorer] = Backend(_blip2_scorer, connect=_load_scorer_weights)
SIGLIP_SCORER: Backend[ImageTextScorer] = Backend(_siglip_scorer, connect=_load_scorer_weights)
REPLAY_SCORER: Backend[ImageTextScorer] = Backend(_replay_scorer, check=_read_recording)
ORACLE_SCORER: Backend[ImageTextScorer] = Backend(_oracle_scorer, reads_geodesic=True)

BUILT_IN_SCORERS = {
    "embedded": "drivenav.semantics.registry:EMBEDDED_SCORER",
    "blip2-itm": "drivenav.semantics.registry:BLIP2_ITM_SCORER",
    "siglip": "drivenav.semantics.registry:SIGLIP_SCORER",
    "replay": "drivenav.semantics.registry:REPLAY_SCORER",
    "oracle": "drivenav.semantics.registry:ORACLE_SCORER",
}
"""drivenav's own scorers (``--scorer``; also declared in pyproject.toml, group ``drivenav.scorers``)."""

SCORER_BACKENDS: ModelRegistry[ImageTextScorer] = ModelRegistry("drivenav.scorers", BUILT_IN_SCORERS, "--scorer")

DEFAULT_SEGMENTER = "filled-box"
"""The box segmenter a box detector uses unless ``--segmenter`` names another: its boxes, filled."""


def model_requirements(spec: ModelSpec) -> frozenset[str]:
    """The privileged inputs the chosen reasoner and grounder need: the embedded stand-ins read ground-truth labels,
    the oracle the geodesic distance too."""
    from drivenav.types import GEODESIC, SEMANTIC

    reads = REASONER_BACKENDS.reads_labels(spec.reasoner) or GROUNDER_BACKENDS.reads_labels(grounder_model(spec))
    geodesic = REASONER_BACKENDS.reads_geodesic(spec.reasoner)
    return frozenset({SEMANTIC} if reads else ()) | frozenset({GEODESIC} if geodesic else ())


def grounder_model(spec: ModelSpec) -> str:
    """The detector that grounds: ``detector``, or for ``remote`` the one its server runs (``detector_served``,
    empty where it is not said)."""
    return spec.detector_served if spec.detector == "remote" else spec.detector


def scorer_requirements(spec: ModelSpec) -> frozenset[str]:
    """The privileged inputs the chosen scorer needs (the embedded stand-in ``semantic``, the oracle ``geodesic``),
    which an agent that scores frames then asks for. Kept apart from :func:`model_requirements`, since only some
    methods score."""
    from drivenav.types import GEODESIC, SEMANTIC

    labels = frozenset({SEMANTIC} if SCORER_BACKENDS.reads_labels(spec.scorer) else ())
    return labels | frozenset({GEODESIC} if SCORER_BACKENDS.reads_geodesic(spec.scorer) else ())


def make_reasoner(spec: ModelSpec) -> Reasoner:
    """The reasoner named by ``spec`` (wrapped in a recorder when ``vlm_record`` is set)."""
    reasoner = REASONER_BACKENDS.get(spec.reasoner).build(spec)
    if spec.vlm_record:
        from drivenav.semantics.replay import RecordingReasoner

        reasoner = RecordingReasoner(reasoner, Path(spec.vlm_record))
    return reasoner


def make_grounder(spec: ModelSpec) -> Grounder:
    """The grounder named by ``spec`` (shadowed by the served grounder at ``detector_shadow_url`` when set), its
    detections checked and at most ``max_detections`` a frame kept (:mod:`drivenav.semantics.checked`)."""
    from drivenav.semantics.checked import CheckedGrounder

    grounder = GROUNDER_BACKENDS.get(spec.detector).build(spec)
    if spec.detector_shadow_url:
        from drivenav.semantics.remote import shadowed

        grounder = shadowed(grounder, spec)
    return CheckedGrounder(grounder, spec.max_detections)


def make_segmenter(spec: ModelSpec) -> BoxSegmenter:
    """The box segmenter named by ``spec`` (for the box detectors)."""
    return SEGMENTER_BACKENDS.get(spec.segmenter).build(spec)


def make_scorer(spec: ModelSpec) -> ImageTextScorer:
    """The image-text scorer named by ``spec`` (the VLFM baseline's value source), its similarities checked
    (:mod:`drivenav.semantics.checked`) and, when ``vlm_record`` is set, recorded as checked (the reasoner's file:
    one recording holds both)."""
    from drivenav.semantics.checked import CheckedScorer

    scorer: ImageTextScorer = CheckedScorer(SCORER_BACKENDS.get(spec.scorer).build(spec))
    if spec.vlm_record:
        from drivenav.semantics.replay import RecordingScorer

        scorer = RecordingScorer(scorer, Path(spec.vlm_record))
    return scorer


def _check_record_path(path: Path) -> None:
    """``--vlm-record`` names a file this process can append to (not a directory, in a writable folder)."""
    if path.is_dir():
        raise InputError(path, "--vlm-record", "a file to append the models' records to", "a directory")
    try:
        with path.open("a", encoding="utf-8"):
            pass
    except OSError as error:
        raise InputError(path, "--vlm-record", "a writable file path", error.strerror or str(error)) from None


def _check_segmenter(spec: ModelSpec) -> None:
    """A segmenter other than the default goes with a box detector (a served one: the server's business)."""
    if spec.detector in BOX_DETECTORS:
        with SEGMENTER_BACKENDS.guard(spec.segmenter, "check"):
            SEGMENTER_BACKENDS.get(spec.segmenter).check(spec)
    elif spec.segmenter != DEFAULT_SEGMENTER and spec.detector != "remote":
        expected = (
            f"{DEFAULT_SEGMENTER} with --detector {spec.detector}, which makes its own masks (a box segmenter serves "
            f"{' and '.join(BOX_DETECTORS)})"
        )
        raise InputError("command line", "--segmenter", expected, spec.segmenter)


def _check_regime(spec: ModelSpec) -> None:
    """A detector regime other than the default goes with the embedded detector, whose presets they are."""
    default = ModelSpec().detector_regime
    if spec.detector_regime != default and not GROUNDER_BACKENDS.get(spec.detector).takes_regime:
        expected = f"{default} with --detector {spec.detector} (the regimes are presets of the embedded detector)"
        raise InputError("command line", "--detector-regime", expected, spec.detector_regime)


def check_models(spec: ModelSpec, connect: bool = True) -> None:
    """Fail fast, before any episode: unknown names, a missing replay or checkpoint file, an unwritable record
    file, an unreachable VLM or grounder server, missing weights (cheap checks first, the reasoner's, grounder's,
    segmenter's and scorer's). ``connect=False`` runs the cheap checks only (a shared detector is loaded by its own
    server process)."""
    roles: tuple[tuple[ModelRegistry[Any], str], ...] = (
        (REASONER_BACKENDS, spec.reasoner),
        (GROUNDER_BACKENDS, spec.detector),
        (SCORER_BACKENDS, spec.scorer),
    )
    backends = [(registry, name, registry.get(name)) for registry, name in roles]
    for registry, name, backend in backends:
        with registry.guard(name, "check"):
            backend.check(spec)
    _check_segmenter(spec)
    _check_regime(spec)
    if spec.detector_shadow_url:
        _check_shadow(spec, connect=False)
    if spec.vlm_record:
        _check_record_path(Path(spec.vlm_record))
    if not connect:
        return
    for registry, name, backend in backends:
        with registry.guard(name, "connect"):
            backend.connect(spec)
    if spec.detector_shadow_url:
        _check_shadow(spec, connect=True)


def _check_shadow(spec: ModelSpec, connect: bool) -> None:
    """The shadow grounder's endpoint (and keys off loopback) or, with ``connect``, that it answers."""
    from drivenav.semantics.remote import SHADOW_OPTION, check_detector_url, reach_server, shadow_spec

    if connect:
        reach_server(shadow_spec(spec), SHADOW_OPTION)
    else:
        check_detector_url(shadow_spec(spec), SHADOW_OPTION)
