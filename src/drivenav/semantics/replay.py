"""Record a reasoner's and a scorer's answers and replay them without the model (reproducible runs of Sec. IV's
VLM questions, of ApexNav's category question, of the floor question and of the VLFM and ApexNav baselines'
image-text scores).

:class:`RecordingReasoner` wraps any reasoner, and :class:`RecordingScorer` any image-text scorer, and each appends
one JSON line per question to a file (both may share one file: one recording of a run holds every kind)::

    {"key": "<sha256>", "kind": "select_direction", "goal": "...", "summary": "...", "answer": {...}}

The key is the SHA-256 of a canonical JSON of the question: its kind and inputs (goal; candidate labels,
bearings, turns and travel times rounded to 1e-4, frontier cells; SHA-256, shape and dtype of every image
array; the description and failed prompts; the verification frames; the scored frame and, where a method brings
its own text, that text). A score's answer is ``{"score": <float>}``, the float exactly as the scorer returned it;
a category question's key is its kind and goal alone; a floor question's is its kind, goal and the SHA-256, shape
and dtype of each view's image, in order, and its answer one of
:data:`~drivenav.semantics.protocols.FLOOR_GUESSES`. :class:`ReplayReasoner` and
:class:`ReplayScorer` answer from such a file, each its own kinds, in recording order when one question was asked
several times. A question missing from the file raises :class:`ReplayMissError`, naming the question: the replay
does not match the run.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.semantics.checked import usable_similarity
from drivenav.semantics.protocols import (
    FLOOR_GUESSES,
    FLOOR_KIND,
    HINTS_KIND,
    JUDGEMENTS,
    Candidate,
    CategoryHints,
    FloorJudgement,
    ImageTextScorer,
    ModelCall,
    Proposal,
    Reasoner,
    ScorePrompt,
    Selection,
    Verdict,
    VerificationFrame,
    View,
)
from drivenav.semantics.wrapped import M, Wrapped
from drivenav.types import GroundTruth, Observation

Answer = Selection | Proposal | Verdict | CategoryHints | FloorJudgement | float
A = TypeVar("A", Selection, Proposal, Verdict, CategoryHints, FloorJudgement, float)
C = TypeVar("C", bound=str)

SCORE = "score"  # the kind of an image-text scorer's question


@dataclass(frozen=True)
class Request:
    """One question in canonical form: its kind, goal and JSON-able inputs, with a readable summary."""

    kind: str
    goal: str
    inputs: JsonObject
    summary: str

    @property
    def key(self) -> str:
        question = {"kind": self.kind, "goal": self.goal, **self.inputs}
        canonical = json.dumps(question, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


class ReplayMissError(InputError):
    """The replay file holds no answer to a question the run asks."""

    def __init__(self, path: Path, request: Request, recorded: int) -> None:
        super().__init__(
            path,
            request.kind,
            f"a recorded answer for the {request.kind} question with goal {request.goal!r} "
            f"({request.summary}; key {request.key[:16]}), but it is not in the file, which holds {recorded} "
            f"{request.kind} answers for that goal: the replay does not match this run",
        )


def array_digest(array: NDArray[Any]) -> str:
    """SHA-256 of an array's bytes, shape and dtype."""
    contiguous = np.ascontiguousarray(array)
    digest = hashlib.sha256(f"{contiguous.shape}{contiguous.dtype.str}".encode())
    digest.update(contiguous.tobytes())
    return digest.hexdigest()


def _number(value: float) -> float | str:
    """Rounded to 1e-4; non-finite values as text (JSON has no NaN or infinity)."""
    return round(value, 4) if math.isfinite(value) else str(value)


def _frame_digest(frame: VerificationFrame) -> dict[str, str]:
    return {"rgb": array_digest(frame.rgb), "mask": array_digest(frame.mask), "overlay": array_digest(frame.overlay)}


def select_request(goal: str, candidates: Sequence[Candidate]) -> Request:
    inputs = {
        "candidates": [
            {
                "label": c.label,
                "bearing": _number(c.bearing),
                "turn": _number(c.turn),
                "travel_time": _number(c.travel_time),
                "frontier_cells": c.frontier_cells,
                "view": None if c.view is None else array_digest(c.view.rgb),
            }
            for c in candidates
        ]
    }
    return Request("select_direction", goal, inputs, f"candidate labels {[c.label for c in candidates]}")


def propose_request(goal: str, view: View, description: str, failed: Sequence[str]) -> Request:
    inputs = {"view": array_digest(view.rgb), "description": description, "failed": list(failed)}
    return Request("propose_prompt", goal, inputs, f"view of direction {view.label}, failed prompts {list(failed)}")


def verify_request(goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Request:
    inputs = {"frame": _frame_digest(frame), "earlier": [_frame_digest(old) for old in earlier]}
    return Request("verify", goal, inputs, f"frame of step {frame.step}, earlier steps {[f.step for f in earlier]}")


def score_request(goal: str, rgb: NDArray[np.uint8], prompt: ScorePrompt | None = None) -> Request:
    """A frame's score; the text is part of the question only where a method brings its own (VLFM's keys stay)."""
    shape = "x".join(str(n) for n in rgb.shape)
    inputs: JsonObject = {"rgb": array_digest(rgb)}
    if prompt is not None:
        inputs["text"] = prompt.text(goal)
    return Request(SCORE, goal, inputs, f"frame of shape {shape}")


def hints_request(goal: str) -> Request:
    return Request(HINTS_KIND, goal, {}, "the category question")


def floor_request(goal: str, views: Sequence[View]) -> Request:
    inputs = {"views": [array_digest(view.rgb) for view in views]}
    return Request(FLOOR_KIND, goal, inputs, f"views of steps {[view.step for view in views]}")


def answer_to_json(answer: Answer) -> JsonObject:
    if isinstance(answer, float):
        return {SCORE: answer}
    if isinstance(answer, Selection):
        return {
            "label": answer.label,
            "target_visible": answer.target_visible,
            "target_label": answer.target_label,
            "descriptions": {str(label): text for label, text in answer.descriptions.items()},
            "fallback": answer.fallback,
            "note": answer.note,
        }
    if isinstance(answer, Proposal):
        return {"phrase": answer.phrase, "fallback": answer.fallback}
    if isinstance(answer, CategoryHints):
        return {
            "similar": list(answer.similar),
            "threshold": answer.threshold,
            "room": answer.room,
            "fallback": answer.fallback,
        }
    if isinstance(answer, FloorJudgement):
        return {"guess": answer.guess, "fallback": answer.fallback, "note": answer.note}
    return {"judgement": answer.judgement, "fallback": answer.fallback}


class AnswerFieldError(ValueError):
    """A recorded answer's field is missing or of the wrong kind: which field, what was expected, what was there."""

    def __init__(self, name: str, expected: str, value: object) -> None:
        self.name, self.expected, self.value = name, expected, value
        super().__init__(f"answer.{name}: expected {expected}, got {value!r}")


_MISSING = object()


def _field(data: JsonObject, name: str, kind: type, expected: str, optional: bool = False) -> Any:
    value = data.get(name, _MISSING)
    if optional and value is None:
        return None
    if value is _MISSING or not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise AnswerFieldError(name, expected, None if value is _MISSING else value)
    return value


def _one_of(data: JsonObject, name: str, allowed: tuple[C, ...]) -> C:
    """A field that must be one of ``allowed`` (a verdict's judgement, a floor's guess)."""
    chosen = next((value for value in allowed if value == data.get(name)), None)
    if chosen is None:
        raise AnswerFieldError(name, " or ".join(allowed), data.get(name))
    return chosen


def _descriptions(data: JsonObject) -> dict[int, str]:
    descriptions = _field(data, "descriptions", dict, "an object mapping direction labels to texts")
    if not all(str(k).isdecimal() and isinstance(v, str) for k, v in descriptions.items()):
        raise AnswerFieldError("descriptions", "an object mapping direction labels to texts", descriptions)
    return {int(label): text for label, text in descriptions.items()}


def _score(data: JsonObject) -> float:
    """A recorded similarity, checked as a scorer's is (:func:`~drivenav.semantics.checked.usable_similarity`:
    one that is not usable was recorded as its fallback 0)."""
    value = data.get(SCORE)
    similarity = usable_similarity(value)
    if similarity is None:
        raise AnswerFieldError(SCORE, "a finite similarity in [-1, 1]", value)
    return similarity


def answer_from_json(kind: str, data: Any) -> Answer:
    """The inverse of :func:`answer_to_json`; a bad field raises :class:`AnswerFieldError` naming it."""
    if not isinstance(data, dict):
        raise AnswerFieldError("", "an object", data)
    if kind == SCORE:
        return _score(data)
    fallback = _field(data, "fallback", bool, "true or false")
    if kind == "select_direction":
        return Selection(
            label=_field(data, "label", int, "a direction label or null", optional=True),
            target_visible=_field(data, "target_visible", bool, "true or false"),
            target_label=_field(data, "target_label", int, "a direction label or null", optional=True),
            descriptions=_descriptions(data),
            fallback=fallback,
            note=_field(data, "note", str, "a text"),
        )
    if kind == "propose_prompt":
        return Proposal(_field(data, "phrase", str, "a text"), fallback=fallback)
    if kind == HINTS_KIND:
        return _hints(data, fallback)
    if kind == FLOOR_KIND:
        return FloorJudgement(_one_of(data, "guess", FLOOR_GUESSES), fallback, _field(data, "note", str, "a text"))
    if kind != "verify":
        kinds = f"select_direction, propose_prompt, verify, {HINTS_KIND}, {FLOOR_KIND} or score"
        raise AnswerFieldError("kind", kinds, kind)
    return Verdict(_one_of(data, "judgement", JUDGEMENTS), fallback=fallback)


def _hints(data: JsonObject, fallback: bool) -> CategoryHints:
    similar = _field(data, "similar", list, "a list of object names")
    if not all(isinstance(name, str) for name in similar):
        raise AnswerFieldError("similar", "a list of object names", similar)
    threshold = data.get("threshold")
    if isinstance(threshold, bool) or not isinstance(threshold, int | float):
        raise AnswerFieldError("threshold", "a number", threshold)
    return CategoryHints(tuple(similar), float(threshold), _field(data, "room", str, "a text"), fallback)


def _append(path: Path, request: Request, answer: Answer) -> None:
    """One record line, written out at once."""
    record = {
        "key": request.key,
        "kind": request.kind,
        "goal": request.goal,
        "summary": request.summary,
        "answer": answer_to_json(answer),
    }
    with path.open("a", encoding="utf-8") as file:
        file.write(json.dumps(record, sort_keys=True) + "\n")


class _Recorder(Wrapped[M]):
    """A model ``inner`` whose answers are recorded to ``path``: its name and its calls are the inner model's."""

    def __init__(self, inner: M, path: Path) -> None:
        super().__init__(inner)
        self.path = Path(path)


class RecordingReasoner(_Recorder[Reasoner]):
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` by asking ``inner`` and recording to ``path``.

    Records are appended (an existing file is extended) and written out after every question.
    """

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        self.inner.begin_episode(goal, truth)

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        return self._record(select_request(goal, candidates), self.inner.select_direction(goal, candidates))

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
        answer = self.inner.propose_prompt(goal, view, description, failed)
        return self._record(propose_request(goal, view, description, failed), answer)

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        return self._record(verify_request(goal, frame, earlier), self.inner.verify(goal, frame, earlier))

    def category_hints(self, goal: str) -> CategoryHints:
        return self._record(hints_request(goal), self.inner.category_hints(goal))

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        return self._record(floor_request(goal, views), self.inner.judge_floor(goal, views))

    def _record(self, request: Request, answer: A) -> A:
        _append(self.path, request, answer)
        return answer


class RecordingScorer(_Recorder[ImageTextScorer]):
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` by asking ``inner`` and recording to
    ``path`` (appended, written out after every score, as :class:`RecordingReasoner` does)."""

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.inner.begin_episode(truth)

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        value = float(self.inner.score(goal, observation, prompt))
        _append(self.path, score_request(goal, observation.rgb, prompt), value)
        return value


class Recording:
    """Every answer of a file written by the recorders, by question key (each line checked when read).

    A file that is missing or malformed raises :class:`~drivenav.errors.InputError` at construction.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._answers: dict[str, list[Answer]] = defaultdict(list)
        self._per_goal: dict[tuple[str, str], int] = defaultdict(int)
        self._served: dict[str, int] = defaultdict(int)
        self._load()

    def _load(self) -> None:
        try:
            lines = self.path.read_text(encoding="utf-8").splitlines()
        except OSError as err:
            raise InputError(self.path, "file", "a readable replay file written by a recording run", str(err)) from err
        except UnicodeDecodeError as err:
            raise InputError(
                self.path,
                "file",
                "a UTF-8 text file written with --vlm-record",
                f"a byte that is not UTF-8 at {err.start}",
            ) from None
        for number, line in enumerate(lines, start=1):
            if line.strip():
                self._add(line, number)

    def _add(self, line: str, number: int) -> None:
        try:
            record = json.loads(line)
            kind, goal = str(record["kind"]), str(record["goal"])
            answer = answer_from_json(kind, record["answer"])
        except AnswerFieldError as err:
            field = f"line {number}: {'kind' if err.name == 'kind' else 'answer.' + err.name}".rstrip(".")
            raise InputError(self.path, field, err.expected, err.value) from None
        except (ValueError, KeyError, TypeError) as err:
            expected = "a JSON record with key, kind, goal and answer"
            raise InputError(self.path, f"line {number}", expected, line) from err
        self._answers[str(record["key"])].append(answer)
        self._per_goal[kind, goal] += 1

    def answer(self, request: Request, expected: type[A], calls: list[ModelCall]) -> A:
        """The next recorded answer to ``request`` (the last one again once all were served), with a ``replayed``
        call appended to ``calls``; :class:`ReplayMissError` if the file holds none."""
        start = time.perf_counter()
        answers = self._answers.get(request.key, [])
        index = min(self._served[request.key], len(answers) - 1)
        answer = answers[index] if answers else None
        if not isinstance(answer, expected):
            raise ReplayMissError(self.path, request, self._per_goal[request.kind, request.goal])
        self._served[request.key] += 1
        calls.append(ModelCall(request.kind, (time.perf_counter() - start) * 1000.0, "replayed"))
        return answer


class ReplayReasoner:
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` from a file written by :class:`RecordingReasoner`
    (its other kinds, such as scores, are read and left alone).

    ``calls`` records outcome ``replayed``. A question not in the file raises :class:`ReplayMissError`; a file
    that is missing or malformed raises :class:`~drivenav.errors.InputError` at construction.
    """

    name = "replay"

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.calls: list[ModelCall] = []
        self._recording = Recording(self.path)

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        self.calls = []

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        return self._recording.answer(select_request(goal, candidates), Selection, self.calls)

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
        return self._recording.answer(propose_request(goal, view, description, failed), Proposal, self.calls)

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        return self._recording.answer(verify_request(goal, frame, earlier), Verdict, self.calls)

    def category_hints(self, goal: str) -> CategoryHints:
        return self._recording.answer(hints_request(goal), CategoryHints, self.calls)

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        return self._recording.answer(floor_request(goal, views), FloorJudgement, self.calls)


class ReplayScorer:
    """Implements :class:`~drivenav.semantics.protocols.ImageTextScorer` from a file written by
    :class:`RecordingScorer` (the reasoner's kinds in it are read and left alone).

    ``calls`` records outcome ``replayed``. A frame and goal not in the file raise :class:`ReplayMissError`; a
    file that is missing or malformed raises :class:`~drivenav.errors.InputError` at construction.
    """

    name = "replay"

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.calls: list[ModelCall] = []
        self._recording = Recording(self.path)

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.calls = []

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        return self._recording.answer(score_request(goal, observation.rgb, prompt), float, self.calls)
