"""A reasoner backed by any OpenAI-compatible chat server: vLLM, SGLang or Ollama serving Qwen3-VL (Sec. V-A).

The paper serves Qwen3-VL-8B with at most 30 images per prompt and asks it three questions (Sec. IV-A c,
IV-B, IV-C; texts in :mod:`drivenav.semantics.prompts`). Each question is one ``POST {base_url}/chat/completions``
with a system message and a user message of text and JPEG data-URI images, at temperature 0. ApexNav's category
question (confusable objects, a threshold, a room) is text only, asked once per category. The floor question
(docs/floors.md), ours, shows views of the floor the agent is on and asks whether the target is likely on it, on
another floor, or either (:func:`floor_text`, :func:`parse_floor`).

Failures never leave the reasoner methods. The transport retries HTTP 429, 5xx and connection failures with
exponential backoff; other 4xx answers, read timeouts (the server may still be busy with the request) and reply
bodies without a message are not retried. A reply that does not fit its schema
(:mod:`drivenav.semantics.answers`) gets one repair request: the same conversation, the bad answer and what was
wrong with it. When that fails too, or the transport gives up, a deterministic fallback answers: the geometric
choice for directions, the goal text or an untried synonym for prompts, "uncertain" for verification, no
knowledge for a category (:meth:`~drivenav.semantics.protocols.CategoryHints.unknown`), "unsure" for a floor. Every
question appends a :class:`~drivenav.semantics.protocols.ModelCall` with outcome ``ok``, ``repaired`` or
``fallback``.
"""

from __future__ import annotations

import base64
import http.client
import io
import json
import logging
import math
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.semantics.answers import (
    AnswerError,
    extract_json_object,
    parse_hints,
    parse_proposal,
    parse_selection,
    parse_verdict,
)
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.prompts import (
    HINTS_SCHEMA,
    HINTS_SYSTEM_PROMPT,
    PROPOSE_SCHEMA,
    SELECT_SCHEMA,
    SYSTEM_PROMPT,
    VERIFY_SCHEMA,
    _answer_with,
    goal_line,
    hints_text,
    propose_text,
    repair_text,
    select_text,
    verify_text,
    view_caption,
)
from drivenav.semantics.protocols import (
    FLOOR_GUESSES,
    FLOOR_KIND,
    HINTS_KIND,
    Candidate,
    CategoryHints,
    FloorJudgement,
    ModelCall,
    Proposal,
    Selection,
    Verdict,
    VerificationFrame,
    View,
)
from drivenav.types import GroundTruth

logger = logging.getLogger(__name__)

T = TypeVar("T", Selection, Proposal, Verdict, CategoryHints, FloorJudgement)
S = TypeVar("S")
Message = JsonObject
Captioned = tuple[str, NDArray[np.uint8]]

MAX_TOKENS = {"select_direction": 1024, "propose_prompt": 128, "verify": 128, HINTS_KIND: 256, FLOOR_KIND: 128}
"""Answer budgets: a selection carries one short description per direction (up to 30)."""

FLOOR_SCHEMA = '{"floor": "this" | "other" | "unsure"}'
"""The floor question's answer (:data:`~drivenav.semantics.protocols.FLOOR_GUESSES`)."""


def floor_caption(index: int, view: View) -> str:
    """The caption put before the ``index``-th (from 1) view of the floor shown."""
    return f"view {index} of this floor (step {view.step})"


def floor_text(goal: str, shown: Sequence[View], omitted: int) -> str:
    """The floor question (docs/floors.md): is the target likely on the floor the ``shown`` views were taken on
    (captioned by :func:`floor_caption`), on another floor, or either? ``omitted`` counts older views of the floor
    left out to respect the image limit."""
    lines = [
        goal_line(goal),
        "The robot is searching a building of several floors for the target. The images are camera views of the "
        'floor it is on now, captioned "view <number> of this floor (step <step>)".',
    ]
    if omitted:
        lines.append(f"({omitted} older views of this floor are not shown: only the latest fit in one request.)")
    lines += [
        "Judging from the kinds of rooms and the objects these views show, is the target likely on this floor, on "
        'another floor, or could it be on either? Answer "this" if it is likely on this floor, "other" if it is '
        'likely on another floor, and "unsure" if you cannot tell.',
        _answer_with(FLOOR_SCHEMA),
    ]
    return "\n".join(lines)


def parse_floor(text: str) -> FloorJudgement:
    """The floor question: one of "this", "other", "unsure" (case and surrounding spaces ignored)."""
    value = extract_json_object(text).get("floor")
    guess = value.strip().lower() if isinstance(value, str) else None
    for allowed in FLOOR_GUESSES:
        if guess == allowed:
            return FloorJudgement(allowed)
    raise AnswerError(f'"floor" must be one of {json.dumps(list(FLOOR_GUESSES))}, got {json.dumps(value)}')


class TransportError(Exception):
    """The server gave no usable reply to a request."""


class _RetryableError(TransportError):
    """A failure worth retrying: HTTP 429, 5xx, or no connection."""


def jpeg_data_uri(rgb: NDArray[np.uint8], quality: int) -> str:
    """An image as a ``data:image/jpeg;base64,...`` URI."""
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).convert("RGB").save(buffer, format="JPEG", quality=quality)
    return "data:image/jpeg;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def nearest_candidates(candidates: Sequence[Candidate], limit: int) -> list[Candidate]:
    """The ``limit`` candidates nearest in travel time (unreachable ones last), in label order."""
    by_time = sorted(candidates, key=lambda c: (c.travel_time if math.isfinite(c.travel_time) else math.inf, c.label))
    return sorted(by_time[:limit], key=lambda c: c.label)


def fallback_phrase(goal: str, failed: Sequence[str]) -> str:
    """The goal text, else its head noun (its last word: "kitchen cabinet" -> "cabinet"), whichever has not failed
    yet (else the goal). Nothing here knows a world's vocabulary: any benchmark's category names work."""
    words = goal.split()
    options = [goal, words[-1]] if len(words) > 1 else [goal]
    tried = {_phrase_key(phrase) for phrase in failed}
    return next((option for option in options if _phrase_key(option) not in tried), goal)


def _phrase_key(phrase: str) -> str:
    """Phrases compared without case, spaces, hyphens or underscores."""
    return "".join(phrase.lower().replace("-", " ").replace("_", " ").split())


def _last(items: Sequence[S], count: int) -> Sequence[S]:
    """The last ``count`` items (at most all of them)."""
    return items[len(items) - count :] if count > 0 else ()


def _reply_content(raw: bytes) -> str:
    """``choices[0].message.content`` of a chat-completion body."""
    try:
        content = json.loads(raw)["choices"][0]["message"]["content"]
    except (ValueError, RecursionError, KeyError, IndexError, TypeError) as err:
        raise TransportError(f"reply without choices[0].message.content: {raw[:200]!r}") from err
    if not isinstance(content, str):
        raise TransportError(f"reply content is not text: {content!r:.200}")
    return content


def _error_detail(err: urllib.error.HTTPError) -> str:
    try:
        body = err.read()[:200].decode("utf-8", "replace")
    except (OSError, http.client.HTTPException):
        body = ""
    return f"HTTP {err.code} {err.reason}" + (f": {body}" if body else "")


def _served_models(raw: bytes) -> list[str]:
    """Model ids of a ``GET /models`` body; [] when it does not list any."""
    try:
        entries = json.loads(raw)["data"]
        return [str(entry["id"]) for entry in entries]
    except (ValueError, KeyError, TypeError):
        return []


class OpenAIReasoner:
    """Implements :class:`~drivenav.semantics.protocols.Reasoner` over an OpenAI-compatible chat API.

    ``api_key`` defaults to ``$DRIVENAV_VLM_API_KEY``, then ``$OPENAI_API_KEY``; without one no
    ``Authorization`` header is sent. ``timeout`` bounds each HTTP request; ``retries`` extra attempts wait
    ``backoff * 2**attempt`` seconds first. ``max_images`` caps the images per request (30 in the paper).
    """

    name = "openai"

    def __init__(
        self,
        base_url: str,
        model: str,
        api_key: str | None = None,
        timeout: float = 60.0,
        retries: int = 3,
        backoff: float = 1.0,
        max_images: int = 30,
        jpeg_quality: int = 85,
    ) -> None:
        if not _is_http_url(base_url):
            raise InputError("--vlm-base-url", "url", "an http(s):// URL such as http://localhost:8000/v1", base_url)
        if not (timeout > 0 and retries >= 0 and backoff >= 0 and max_images >= 2 and 1 <= jpeg_quality <= 95):
            raise ValueError(
                "need timeout > 0, retries >= 0, backoff >= 0, max_images >= 2 and 1 <= jpeg_quality <= 95, got "
                f"{timeout}, {retries}, {backoff}, {max_images}, {jpeg_quality}"
            )
        self.base_url = base_url.rstrip("/")
        self.model = model
        self.api_key = api_key if api_key is not None else _key_from_environment()
        self.timeout = timeout
        self.retries = retries
        self.backoff = backoff
        self.max_images = max_images
        self.jpeg_quality = jpeg_quality
        self.calls: list[ModelCall] = []
        self._geometric = GeometricReasoner()

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        """Start a fresh call record (the model never sees ground truth)."""
        self.calls = []
        self._geometric.begin_episode(goal, None)

    def check_connection(self, timeout: float = 5.0) -> None:
        """``GET {base_url}/models``; :class:`InputError` when unreachable or when it does not serve the model."""
        try:
            with urllib.request.urlopen(self._request("/models", None), timeout=timeout) as response:
                raw = response.read()
        except urllib.error.HTTPError as err:
            hint = " (OpenAI-compatible servers usually serve under /v1)" if err.code == 404 else ""
            raise self._unreachable(_error_detail(err) + hint) from err
        except urllib.error.URLError as err:
            raise self._unreachable(str(err.reason)) from err
        except (OSError, http.client.HTTPException) as err:
            raise self._unreachable(str(err) or type(err).__name__) from err
        served = _served_models(raw)
        if served and self.model not in served:
            expected = f"one of the models served at {self.base_url}: {served}"
            raise InputError("--vlm-model", "model", expected, self.model)

    def _unreachable(self, reason: str) -> InputError:
        return InputError(
            "--vlm-base-url",
            "url",
            f"a reachable OpenAI-compatible server, but cannot reach the VLM server at {self.base_url}: {reason}; "
            "start vLLM/SGLang/Ollama there or pass --vlm-base-url",
        )

    def select_direction(self, goal: str, candidates: Sequence[Candidate]) -> Selection:
        """Question (i), Sec. IV-A c: the nearest ``max_images`` candidates' views; fallback: geometric choice."""
        if not candidates:
            self.calls.append(ModelCall("select_direction", 0.0, "ok"))
            return Selection(label=None, note="no candidates")
        offered = nearest_candidates(candidates, self.max_images)
        labels = {candidate.label for candidate in offered}
        images = [(view_caption(c.label), c.view.rgb) for c in offered if c.view is not None]

        def fallback(reason: str) -> Selection:
            chosen = self._geometric.select_direction(goal, candidates)
            return replace(chosen, fallback=True, note=f"fallback ({reason}); {chosen.note}")

        return self._ask(
            "select_direction",
            self._messages(select_text(goal, offered, len(candidates) - len(offered)), images),
            lambda text: parse_selection(text, labels),
            SELECT_SCHEMA,
            fallback,
        )

    def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
        """Question (ii), Sec. IV-B: a phrase for the target-facing view; fallback: goal or untried synonym."""
        return self._ask(
            "propose_prompt",
            self._messages(propose_text(goal, description, failed), [("target-facing view", view.rgb)]),
            lambda text: parse_proposal(text, failed),
            PROPOSE_SCHEMA,
            lambda reason: Proposal(fallback_phrase(goal, failed), fallback=True),
        )

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        """Question (iii), Sec. IV-C: earlier overlays, the current frame and its overlay; fallback: uncertain."""
        shown = _last(earlier, min(len(earlier), self.max_images - 2))
        images: list[Captioned] = [
            (f"earlier frame {i + 1} (step {old.step}) with the candidate highlighted", old.overlay)
            for i, old in enumerate(shown)
        ]
        images += [
            (f"current frame (step {frame.step})", frame.rgb),
            ("current frame with the candidate's mask overlaid", frame.overlay),
        ]
        return self._ask(
            "verify",
            self._messages(verify_text(goal, len(shown)), images),
            parse_verdict,
            VERIFY_SCHEMA,
            lambda reason: Verdict("uncertain", fallback=True),
        )

    def category_hints(self, goal: str) -> CategoryHints:
        """ApexNav's category question, text only; fallback: no knowledge (no confusable objects, the middle
        threshold, any room)."""
        return self._ask(
            HINTS_KIND,
            self._messages(hints_text(goal), [], HINTS_SYSTEM_PROMPT),
            lambda text: parse_hints(text, goal),
            HINTS_SCHEMA,
            lambda reason: CategoryHints.unknown(fallback=True),
        )

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        """The floor question: the latest ``max_images`` views of the floor; fallback: unsure. Without views there
        is nothing to ask: unsure, with no request."""
        if not views:
            self.calls.append(ModelCall(FLOOR_KIND, 0.0, "ok"))
            return FloorJudgement("unsure", note="no views")
        shown = _last(views, min(len(views), self.max_images))
        images = [(floor_caption(i + 1, view), view.rgb) for i, view in enumerate(shown)]
        return self._ask(
            FLOOR_KIND,
            self._messages(floor_text(goal, shown, len(views) - len(shown)), images),
            parse_floor,
            FLOOR_SCHEMA,
            lambda reason: FloorJudgement("unsure", fallback=True, note=f"fallback ({reason})"),
        )

    def _messages(self, text: str, images: Sequence[Captioned], system: str = SYSTEM_PROMPT) -> list[Message]:
        """System prompt, then the question text followed by each caption and its JPEG image."""
        content: list[JsonObject] = [{"type": "text", "text": text}]
        for caption, rgb in images:
            content.append({"type": "text", "text": caption})
            content.append({"type": "image_url", "image_url": {"url": jpeg_data_uri(rgb, self.jpeg_quality)}})
        return [{"role": "system", "content": system}, {"role": "user", "content": content}]

    def _ask(
        self,
        kind: str,
        messages: list[Message],
        parse: Callable[[str], T],
        schema: str,
        fallback: Callable[[str], T],
    ) -> T:
        """One question: answer, one repair if malformed, else the fallback; records the :class:`ModelCall`."""
        start = time.perf_counter()
        try:
            answer, outcome = self._converse(kind, messages, parse, schema)
        except (TransportError, AnswerError) as err:
            logger.warning("VLM %s at %s failed, using the fallback answer: %s", kind, self.base_url, err)
            answer, outcome = fallback(str(err)), "fallback"
        self.calls.append(ModelCall(kind, (time.perf_counter() - start) * 1000.0, outcome))
        return answer

    def _converse(self, kind: str, messages: list[Message], parse: Callable[[str], T], schema: str) -> tuple[T, str]:
        text = self._complete(kind, messages)
        try:
            return parse(text), "ok"
        except AnswerError as err:
            logger.info("VLM %s answer malformed (%s); asking once for a repair", kind, err)
            repair = [
                *messages,
                {"role": "assistant", "content": text},
                {"role": "user", "content": repair_text(str(err), schema)},
            ]
            return parse(self._complete(kind, repair)), "repaired"

    def _complete(self, kind: str, messages: list[Message]) -> str:
        """The reply text of one chat completion, retrying retryable failures with exponential backoff."""
        payload = {"model": self.model, "messages": messages, "temperature": 0, "max_tokens": MAX_TOKENS[kind]}
        body = json.dumps(payload).encode("utf-8")
        attempt = 0
        while True:
            try:
                return self._post(body)
            except _RetryableError as err:
                if attempt == self.retries:
                    raise TransportError(f"{err} (gave up after {attempt + 1} attempts)") from err
                delay = self.backoff * 2**attempt
                logger.info("VLM %s attempt %d failed (%s); retrying in %.2f s", kind, attempt + 1, err, delay)
                time.sleep(delay)
                attempt += 1

    def _post(self, body: bytes) -> str:
        try:
            with urllib.request.urlopen(self._request("/chat/completions", body), timeout=self.timeout) as response:
                raw = response.read()
        except urllib.error.HTTPError as err:
            retry = err.code == 429 or err.code >= 500
            raise (_RetryableError if retry else TransportError)(_error_detail(err)) from err
        except TimeoutError as err:
            raise TransportError(f"no reply within {self.timeout} s") from err
        except urllib.error.URLError as err:
            raise _RetryableError(f"cannot connect: {err.reason}") from err
        except (OSError, http.client.HTTPException) as err:
            raise _RetryableError(f"connection failed: {err or type(err).__name__}") from err
        return _reply_content(raw)

    def _request(self, path: str, body: bytes | None) -> urllib.request.Request:
        headers = {"Content-Type": "application/json", "Accept": "application/json"}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        return urllib.request.Request(self.base_url + path, data=body, headers=headers)


def _is_http_url(url: str) -> bool:
    try:
        parts = urllib.parse.urlsplit(url)
        return parts.scheme in ("http", "https") and bool(parts.hostname) and parts.port != 0
    except ValueError:  # a malformed address or port
        return False


def _key_from_environment() -> str | None:
    return os.environ.get("DRIVENAV_VLM_API_KEY") or os.environ.get("OPENAI_API_KEY") or None
