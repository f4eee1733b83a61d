"""Parsing and validation of the VLM's JSON answers to the three questions (Sec. IV-A c, IV-B, IV-C) and to
ApexNav's category question.

A model may wrap its answer in Markdown fences or surround it with prose, so the first JSON object in the text
is taken (after any ``</think>``, which ends a reasoning model's thoughts). Each parser checks what the
question's schema (:mod:`drivenav.semantics.prompts`) demands and raises :class:`AnswerError` with a one-line
statement of the first problem; the reasoner sends that statement back in its single repair request.
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from typing import Any

from drivenav.jsonstream import JsonObject
from drivenav.semantics.prompts import MAX_PHRASE_WORDS, MAX_ROOM_WORDS
from drivenav.semantics.protocols import (
    HINT_THRESHOLDS,
    JUDGEMENTS,
    MAX_SIMILAR_OBJECTS,
    CategoryHints,
    Proposal,
    Selection,
    Verdict,
)

MAX_NAMED_OBJECTS = 5
"""The most confusable objects an answer may name (the question asks for 3 to 5)."""


class AnswerError(ValueError):
    """A model answer that does not fit its schema; the message says what is wrong, for the repair request."""


def extract_json_object(text: str) -> JsonObject:
    """The first JSON object in ``text`` after any ``</think>`` (fences and prose around it are ignored)."""
    text = text.rsplit("</think>", 1)[-1]
    decoder = json.JSONDecoder()
    start = text.find("{")
    while start != -1:
        try:
            value, _ = decoder.raw_decode(text, start)
        except (ValueError, RecursionError):
            value = None
        if isinstance(value, dict):
            return value
        start = text.find("{", start + 1)
    raise AnswerError("the answer contains no JSON object")


def _label(obj: Mapping[str, Any], key: str, labels: Collection[int]) -> int:
    value = obj.get(key)
    if not isinstance(value, int) or isinstance(value, bool):
        raise AnswerError(f'"{key}" must be an integer direction label, got {json.dumps(value)}')
    if value not in labels:
        raise AnswerError(f'"{key}" is {value}, which is not one of the offered directions {sorted(labels)}')
    return value


def _descriptions(value: Any, labels: Collection[int]) -> dict[int, str]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise AnswerError(f'"descriptions" must be an object mapping labels to texts, got {json.dumps(value)}')
    parsed: dict[int, str] = {}
    for key, text in value.items():
        if not (key.strip().isdecimal() and int(key) in labels):
            raise AnswerError(f'"descriptions" has key {json.dumps(key)}, which is not an offered direction label')
        if not isinstance(text, str):
            raise AnswerError(f'"descriptions"["{key}"] must be a string, got {json.dumps(text)}')
        parsed[int(key)] = text.strip()
    return parsed


def parse_selection(text: str, labels: Collection[int]) -> Selection:
    """Question (i): the chosen direction, target visibility and descriptions, all labels among ``labels``.

    ``target_direction`` is required when ``target_visible`` is true and ignored otherwise.
    """
    obj = extract_json_object(text)
    label = _label(obj, "direction", labels)
    visible = obj.get("target_visible")
    if not isinstance(visible, bool):
        raise AnswerError(f'"target_visible" must be true or false, got {json.dumps(visible)}')
    target = _label(obj, "target_direction", labels) if visible else None
    descriptions = _descriptions(obj.get("descriptions"), labels)
    return Selection(label=label, target_visible=visible, target_label=target, descriptions=descriptions)


def parse_proposal(text: str, failed: Sequence[str]) -> Proposal:
    """Question (ii): a non-empty noun phrase of at most six words that is not a failed prompt."""
    phrase = extract_json_object(text).get("phrase")
    if not isinstance(phrase, str) or not phrase.strip():
        raise AnswerError(f'"phrase" must be a non-empty string, got {json.dumps(phrase)}')
    words = phrase.split()
    if len(words) > MAX_PHRASE_WORDS:
        raise AnswerError(f'"phrase" has {len(words)} words; at most {MAX_PHRASE_WORDS} are allowed')
    cleaned = " ".join(words)
    if cleaned.lower() in {" ".join(f.split()).lower() for f in failed}:
        raise AnswerError(f'"phrase" {json.dumps(cleaned)} already failed; propose a different one')
    return Proposal(cleaned)


def parse_verdict(text: str) -> Verdict:
    """Question (iii): one of "sure", "uncertain", "not" (case and surrounding spaces ignored)."""
    value = extract_json_object(text).get("judgement")
    judgement = value.strip().lower() if isinstance(value, str) else None
    for allowed in JUDGEMENTS:
        if judgement == allowed:
            return Verdict(allowed)
    raise AnswerError(f'"judgement" must be one of {json.dumps(list(JUDGEMENTS))}, got {json.dumps(value)}')


def parse_hints(text: str, goal: str) -> CategoryHints:
    """The category question: at most five object names (the goal itself and repeats dropped, the first
    :data:`~drivenav.semantics.protocols.MAX_SIMILAR_OBJECTS` kept), a threshold within
    :data:`~drivenav.semantics.protocols.HINT_THRESHOLDS` and a room of at most four words; names lower-cased."""
    obj = extract_json_object(text)
    names = obj.get("similar_objects")
    if not isinstance(names, list) or not all(isinstance(name, str) for name in names):
        raise AnswerError(f'"similar_objects" must be a list of object names, got {json.dumps(names)}')
    if len(names) > MAX_NAMED_OBJECTS:
        raise AnswerError(f'"similar_objects" names {len(names)} objects; at most {MAX_NAMED_OBJECTS} are allowed')
    own = " ".join(goal.lower().split())
    cleaned = dict.fromkeys(" ".join(name.lower().split()) for name in names)
    similar = tuple(name for name in cleaned if name and name != own)[:MAX_SIMILAR_OBJECTS]
    threshold = obj.get("threshold")
    low, high = HINT_THRESHOLDS
    if isinstance(threshold, bool) or not isinstance(threshold, int | float) or not low <= threshold <= high:
        raise AnswerError(f'"threshold" must be a number between {low} and {high}, got {json.dumps(threshold)}')
    room = obj.get("room")
    words = room.lower().split() if isinstance(room, str) else []
    if not 1 <= len(words) <= MAX_ROOM_WORDS:
        raise AnswerError(f'"room" must name a room in at most {MAX_ROOM_WORDS} words, got {json.dumps(room)}')
    return CategoryHints(similar, float(threshold), " ".join(words))
