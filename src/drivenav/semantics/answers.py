"""Parsing and validation of the VLM's JSON answers to the three questions (Sec. IV-A c, IV-B, IV-C).

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
from drivenav.semantics.prompts import MAX_PHRASE_WORDS
from drivenav.semantics.protocols import JUDGEMENTS, Proposal, Selection, Verdict


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
