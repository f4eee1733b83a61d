"""The model interfaces: DRIVE-Nav's reasoner (the VLM's role) and grounder (the segmenter's role), and the
image-text scorer of the VLFM and ApexNav baselines (BLIP-2 ITM's role).

Backends (a geometric stand-in, the embedded world's ground-truth detector, real VLMs, SAM3, OWLv2, BLIP-2,
SigLIP) implement these protocols; the agent only sees them. Positions and bearings are in the episode frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from drivenav.packing import DeferredImage, PackedImage
from drivenav.types import GroundTruth, Observation, Pose


@dataclass(frozen=True, eq=False, init=False)
class View:
    """A representative view of a direction (Sec. IV-A c): the frame whose yaw was closest to its bearing.

    ``bearing`` is the direction's bearing when the view was taken and ``error`` = |yaw - bearing| then.
    ``semantic`` is the world's instance image where it has one (the embedded reasoner reads it). No depth is
    kept: the paper's VLM sees images only, and an episode holds dozens of views (a depth image is 36 % of one).
    The images are held as given, compressed (:class:`~drivenav.packing.PackedImage`) or, for a simulated RGB
    image nobody has read, as its rendering call (:class:`~drivenav.packing.DeferredImage`), and are unpacked or
    rendered on each read.
    """

    label: int
    pose: Pose
    bearing: float
    error: float
    step: int
    _rgb: NDArray[np.uint8] | PackedImage | DeferredImage
    _semantic: NDArray[np.int32] | PackedImage | None

    def __init__(
        self,
        label: int,
        rgb: NDArray[np.uint8] | PackedImage | DeferredImage,
        semantic: NDArray[np.int32] | PackedImage | None,
        pose: Pose,
        bearing: float,
        error: float,
        step: int,
    ) -> None:
        object.__setattr__(self, "label", label)
        object.__setattr__(self, "pose", pose)
        object.__setattr__(self, "bearing", bearing)
        object.__setattr__(self, "error", error)
        object.__setattr__(self, "step", step)
        object.__setattr__(self, "_rgb", rgb)
        object.__setattr__(self, "_semantic", semantic)

    @property
    def rgb(self) -> NDArray[np.uint8]:
        return self._rgb if isinstance(self._rgb, np.ndarray) else self._rgb.unpack()

    @property
    def semantic(self) -> NDArray[np.int32] | None:
        return self._semantic.unpack() if isinstance(self._semantic, PackedImage) else self._semantic

    def relabelled(self, label: int, bearing: float, error: float) -> View:
        """The same frame as the view of direction ``label`` at ``bearing`` (its images shared, not copied)."""
        return View(label, self._rgb, self._semantic, self.pose, bearing, error, self.step)


@dataclass(frozen=True)
class Candidate:
    """One option offered to the reasoner: a tracked direction (or a raw frontier in the frontier baseline).

    ``turn`` is the signed angle from the robot heading to ``bearing`` in ``(-pi, pi]``; ``travel_time`` the
    weighted-FMM time to its nearest frontier cell; ``frontier_cells`` how many frontier cells support it (its
    unexplored extent); ``view`` its representative view, if any; ``current`` marks the direction being
    followed (a VLM prompt says "you are heading toward ...").
    ``frontiers``: where exploring it leads, its frontier waypoints and farthest point (episode frame, at the
    robot's height); only privileged reasoners read them (the oracle's geodesic choice, docs/regimes.md).
    """

    label: int
    bearing: float
    turn: float
    travel_time: float
    frontier_cells: int
    view: View | None = None
    current: bool = False  # the direction the robot is following now
    frontiers: tuple[Pose, ...] = ()


@dataclass(frozen=True)
class Selection:
    """The reasoner's answer to "which direction next?" (Sec. IV-A c, IV-B).

    ``label`` is the chosen candidate (None: nothing worth exploring); ``target_visible`` and ``target_label``
    report whether and in which view the target appears; ``descriptions`` are short per-direction texts kept for
    prompt enrichment; ``fallback`` marks a deterministic fallback after a malformed answer.
    """

    label: int | None
    target_visible: bool = False
    target_label: int | None = None
    descriptions: Mapping[int, str] = field(default_factory=dict)
    fallback: bool = False
    note: str = ""


Judgement = Literal["sure", "uncertain", "not"]
"""Cross-frame verification answers (Sec. IV-C): completely sure, uncertain, definitely not."""

JUDGEMENTS: tuple[Judgement, ...] = ("sure", "uncertain", "not")


@dataclass(frozen=True)
class Proposal:
    """A detector-oriented noun phrase proposed for prompt enrichment (Sec. IV-B)."""

    phrase: str
    fallback: bool = False


@dataclass(frozen=True)
class VerificationFrame:
    """One target-approach frame: the image, the candidate's mask and its overlay (Sec. IV-C)."""

    rgb: NDArray[np.uint8]
    mask: NDArray[np.bool_]
    overlay: NDArray[np.uint8]
    semantic: NDArray[np.int32] | None
    pose: Pose
    step: int


@dataclass(frozen=True)
class Verdict:
    """The reasoner's judgement of a candidate in one frame."""

    judgement: Judgement
    fallback: bool = False


@dataclass(frozen=True)
class ModelCall:
    """Bookkeeping of one model call for the episode record: its kind, latency and outcome.

    ``kind`` is ``select_direction``, ``propose_prompt``, ``verify``, ``category_hints``, ``judge_floor`` or
    ``score``; ``outcome``
    is ``ok``, ``repaired`` (a malformed answer fixed by one repair request), ``fallback`` (deterministic answer
    after a failure), ``replayed`` or ``cached`` (a category's hints asked earlier in the run, answered from the
    agent's cache without a model).
    """

    kind: str
    latency_ms: float
    outcome: str


HINTS_KIND = "category_hints"
"""The :class:`ModelCall` kind of the category question (:meth:`Reasoner.category_hints`)."""

HINT_THRESHOLDS = (0.25, 0.65)
"""The range of a category's detection threshold (ApexNav ``llm/prompt/get_llm_answer.py``: "a confidence
threshold between 0.25 and 0.65", apple 0.25 ... bed 0.65)."""

MAX_SIMILAR_OBJECTS = 4
"""ApexNav's object clusters hold five label slots, the target's and four others (``object_map2d.cpp``); its prompt
asks for 3-5 confusable objects, so a fifth would overflow: at most four are kept."""

EVERYWHERE = "everywhere"
"""The room of a category found in any room (ApexNav's answer then, and its value-map prompt without a room)."""


@dataclass(frozen=True)
class CategoryHints:
    """What a language model knows of a target category before the search (ApexNav, Zhang et al., RA-L 2025:
    ``llm/prompt/get_llm_answer.py``): the objects a detector may confuse with it (detected as competing labels),
    the detection confidence at which a fused object counts as the target (within :data:`HINT_THRESHOLDS`), and
    the room it is most likely in (:data:`EVERYWHERE` when none). ``fallback`` marks the deterministic answer of a
    reasoner that could not answer (:meth:`unknown`)."""

    similar: tuple[str, ...]
    threshold: float
    room: str
    fallback: bool = False

    @staticmethod
    def unknown(fallback: bool = False) -> CategoryHints:
        """No knowledge: no confusable objects, the middle of the threshold range, any room."""
        return CategoryHints((), round(sum(HINT_THRESHOLDS) / 2.0, 4), EVERYWHERE, fallback)


FLOOR_KIND = "judge_floor"
"""The :class:`ModelCall` kind of the floor question (:meth:`Reasoner.judge_floor`)."""

FloorGuess = Literal["this", "other", "unsure"]
"""The floor question's answers: the target is likely on the floor shown, likely on another floor, or either."""

FLOOR_GUESSES: tuple[FloorGuess, ...] = ("this", "other", "unsure")


@dataclass(frozen=True)
class FloorJudgement:
    """The reasoner's answer to "is the target on this floor?" (docs/floors.md, "The floor rule"); ``fallback``
    marks the deterministic ``unsure`` of a reasoner that could not answer."""

    guess: FloorGuess
    fallback: bool = False
    note: str = ""


def category_key(name: str, truth: GroundTruth | None) -> str:
    """The world's category for a name or synonym (ground truth), else the name itself lower-cased and stripped."""
    vocabulary = truth.vocabulary if truth is not None else None
    canonical = vocabulary.canonical(name) if vocabulary is not None else None
    return canonical or name.strip().lower()


class Reasoner(Protocol):
    """The VLM's three questions (paper Sec. IV-A c, IV-B, IV-C), ApexNav's category question and the floor
    question, behind one interface.

    ``calls`` grows by one :class:`ModelCall` per question asked. Nothing a model returns may raise out of these
    methods: malformed answers are repaired once, then replaced by a deterministic fallback.
    """

    name: str
    calls: list[ModelCall]

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        """Start an episode; ``truth`` is the world's ground truth, given only to stand-ins that need it."""
        ...

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection: ...

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal: ...

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict: ...

    def category_hints(self, goal: str) -> CategoryHints:
        """ApexNav's question about the target category (text only, once per category and run: the agent caches
        the answer), :class:`CategoryHints`."""
        ...

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        """The floor question (docs/floors.md): from views of the floor the agent is on, whether the target is
        likely on it, :class:`FloorJudgement`."""
        ...


@dataclass(frozen=True)
class Detection:
    """One grounded instance of a phrase: a boolean mask over the image and a confidence in [0, 1].

    What a grounder returns is checked where it is built (:mod:`drivenav.semantics.checked`): a detection with a
    score outside [0, 1] (NaN included) or a mask of another size is dropped, an integer mask made boolean.
    """

    mask: NDArray[np.bool_]
    score: float
    phrase: str


class Grounder(Protocol):
    """Open-vocabulary segmentation of a phrase in the current frame (SAM3's role): the :class:`Detection` s found,
    at most ``models.max_detections`` of them kept (the best scores)."""

    name: str

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Start an episode (``truth``: ground truth for stand-ins only; ``seed``: any randomness)."""
        ...

    def segment(self, observation: Observation, phrase: str) -> list[Detection]: ...


@runtime_checkable
class Prefetching(Protocol):
    """A grounder that can be told early which phrases a frame will be segmented for (a served one: the requests go
    out at once and the server grounds the frame while the agent maps it). A grounder without :meth:`prefetch`
    simply grounds when asked; :func:`prefetch` tells one that has it."""

    def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None: ...


def prefetch(grounder: Grounder, observation: Observation, phrases: Sequence[str]) -> None:
    """Tell ``grounder`` that ``observation`` will be segmented for ``phrases`` (where it can make use of it)."""
    if isinstance(grounder, Prefetching):
        grounder.prefetch(observation, phrases)


@dataclass(frozen=True)
class ScorePrompt:
    """The text a frame is scored against, when a method brings its own: ``template`` with ``{target}`` (the goal)
    and ``{room}`` (``room``), e.g. ApexNav's "Seems like there is a {room} or a {target} ahead?"."""

    template: str
    room: str = ""

    def text(self, goal: str) -> str:
        return self.template.format(target=goal, room=self.room)


class ImageTextScorer(Protocol):
    """How well a frame matches a text about the target: the value VLFM spreads over its map (Yokoyama et al.,
    ICRA 2024; BLIP-2 ITM's cosine with "Seems like there is a {target} ahead."), and ApexNav's with its own text.

    ``score`` returns one similarity for the whole frame, higher meaning more promising; its scale is the
    backend's own within [-1, 1] (BLIP-2's cosine, SigLIP's probability, the embedded stand-in's value in
    [0, 1)), and only comparisons within one backend matter. ``goal`` is the target's name: the backend puts it
    into its text, VLFM's by default or ``prompt``'s where one is given.
    ``observation`` is the current frame: real models read its RGB image, stand-ins its instance image where the
    world has one (without it they answer a neutral 0), so a world's deferred RGB image is rendered only for
    models that look at it. ``calls`` grows by one :class:`ModelCall` of kind ``score`` per frame scored. Nothing
    a model returns may raise out of ``score``: a similarity that is not a finite number in [-1, 1] is a
    ``fallback`` call answering 0 (checked where the scorer is built, :mod:`drivenav.semantics.checked`).
    """

    name: str
    calls: list[ModelCall]

    def begin_episode(self, truth: GroundTruth | None) -> None:
        """Start an episode; ``truth`` is the world's ground truth, given only to stand-ins that need it."""
        ...

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float: ...
