"""The ``openai`` reasoner against the fake OpenAI-compatible server on 127.0.0.1 (Sec. IV-A c, IV-B, IV-C)."""

from __future__ import annotations

import base64
import io
import json
import logging
import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from PIL import Image

from drivenav.errors import InputError
from drivenav.semantics.answers import AnswerError, extract_json_object, parse_proposal, parse_selection, parse_verdict
from drivenav.semantics.fake_vlm_server import FAKE_FLOOR, fake_answer, fake_stats, start_fake_server
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.openai_backend import FLOOR_SCHEMA, OpenAIReasoner, fallback_phrase, floor_text, parse_floor
from drivenav.semantics.prompts import SYSTEM_PROMPT
from drivenav.semantics.protocols import (
    FLOOR_GUESSES,
    Candidate,
    FloorGuess,
    FloorJudgement,
    Reasoner,
    VerificationFrame,
    View,
)
from drivenav.semantics.replay import RecordingReasoner
from drivenav.types import Pose

GOAL = "chair"
MODEL = "fake-vlm"
StartServer = Callable[..., str]


def image(seed: int, shape: tuple[int, int] = (48, 64)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (*shape, 3), dtype=np.uint8)


def view(label: int) -> View:
    rgb = image(label)
    return View(label, rgb, None, Pose(0.0, 0.0, 0.0), 0.1, 0.05, 3)


def floor_views(count: int, first: int = 1) -> list[View]:
    """``count`` views of one floor, taken every 15 steps, each image its own."""
    return [View(i, image(50 + i), None, Pose(0.0, 0.0, 0.0), 0.0, 0.0, 15 * i) for i in range(first, first + count)]


def candidates(labels: list[int]) -> list[Candidate]:
    """Candidates whose travel time grows with the label, so the nearest ones have the smallest labels."""
    return [Candidate(label, 0.2 * label, 0.1 * label, 1.0 + label, 40 - label, view(label)) for label in labels]


def frame(seed: int, step: int) -> VerificationFrame:
    rgb = image(seed)
    mask = np.zeros(rgb.shape[:2], bool)
    mask[10:20, 10:30] = True
    return VerificationFrame(rgb, mask, image(seed + 100), None, Pose(0.0, 0.0, 0.0), step)


@pytest.fixture
def server() -> Iterator[StartServer]:
    """Start fake servers (stopped at teardown, and by themselves after 30 s in any case)."""
    stops: list[Callable[[], None]] = []

    def start(mode: str, **options: Any) -> str:
        url, stop = start_fake_server(mode, lifetime=30.0, **options)
        stops.append(stop)
        return url

    yield start
    for stop in stops:
        stop()


def reasoner(url: str, **options: Any) -> OpenAIReasoner:
    settings: dict[str, Any] = {"timeout": 2.0, "retries": 2, "backoff": 0.01} | options
    return OpenAIReasoner(url, MODEL, **settings)


def ask_all(r: Reasoner) -> tuple[Any, Any, Any]:
    """One question of each kind."""
    offered = candidates([5, 3, 8])
    return (
        r.select_direction(GOAL, offered),
        r.propose_prompt(GOAL, offered[0].view or view(0), "a dining room", []),
        r.verify(GOAL, frame(1, 10), [frame(2, 8)]),
    )


def outcomes(r: Reasoner) -> list[str]:
    return [call.outcome for call in r.calls]


def user_parts(body: dict[str, Any]) -> list[dict[str, Any]]:
    messages = body["messages"]
    assert messages[0]["role"] == "system"
    parts: list[dict[str, Any]] = messages[1]["content"]
    return parts


def image_urls(body: dict[str, Any]) -> list[str]:
    return [part["image_url"]["url"] for part in user_parts(body) if part["type"] == "image_url"]


@pytest.mark.parametrize("mode", ["ok", "fenced"])
def test_valid_and_fenced_answers_are_parsed(server: StartServer, mode: str) -> None:
    url = server(mode)
    r = reasoner(url)
    selection, proposal, verdict = ask_all(r)
    assert selection.label == 3  # the fake picks the first label listed; the list is in label order
    assert not selection.target_visible and selection.target_label is None
    assert set(selection.descriptions) == {3, 5, 8} and "direction 8" in selection.descriptions[8]
    assert (proposal.phrase, verdict.judgement) == (GOAL, "sure")
    assert not (selection.fallback or proposal.fallback or verdict.fallback)
    assert outcomes(r) == ["ok"] * 3
    assert all(call.latency_ms > 0 for call in r.calls)
    assert fake_stats(url)["chat_requests"] == 3


def test_request_payload_follows_the_chat_completions_schema(server: StartServer) -> None:
    url = server("ok")
    ask_all(reasoner(url))
    select_body, propose_body, verify_body = fake_stats(url)["bodies"]
    for body in (select_body, propose_body, verify_body):
        assert body["model"] == MODEL and body["temperature"] == 0 and body["max_tokens"] > 0
        assert user_parts(body)[0]["type"] == "text" and GOAL in user_parts(body)[0]["text"]
    captions = [part["text"] for part in user_parts(select_body) if part["type"] == "text"][1:]
    assert captions == ["view of direction 3", "view of direction 5", "view of direction 8"]
    assert [len(image_urls(body)) for body in (select_body, propose_body, verify_body)] == [3, 1, 3]


def test_images_are_jpeg_data_uris_and_at_most_30_per_request(server: StartServer) -> None:
    url = server("ok")
    r = reasoner(url)
    labels = list(range(1, 36))
    selection = r.select_direction(GOAL, candidates(labels[::-1]))
    body = fake_stats(url)["bodies"][-1]
    urls = image_urls(body)
    assert len(urls) == 30
    for data_uri in urls:
        prefix, encoded = data_uri.split(",", 1)
        assert prefix == "data:image/jpeg;base64"
        decoded = Image.open(io.BytesIO(base64.b64decode(encoded)))
        assert decoded.format == "JPEG" and decoded.size == (64, 48)
    text = user_parts(body)[0]["text"]
    assert "5 farther directions are not offered" in text
    assert "direction 30:" in text and "direction 31:" not in text  # the 30 nearest in travel time
    assert selection.label == 1


def test_verify_keeps_the_most_recent_earlier_frames_within_the_image_limit(server: StartServer) -> None:
    url = server("ok")
    r = reasoner(url, max_images=4)
    earlier = [frame(10 + i, step=i) for i in range(5)]
    assert r.verify(GOAL, frame(1, 9), earlier).judgement == "sure"
    parts = user_parts(fake_stats(url)["bodies"][-1])
    captions = [part["text"] for part in parts if part["type"] == "text"][1:]
    assert len(image_urls(fake_stats(url)["bodies"][-1])) == 4
    assert captions[:2] == [f"earlier frame {i} (step {s}) with the candidate highlighted" for i, s in ((1, 3), (2, 4))]


def test_garbage_gets_one_repair_then_the_deterministic_fallback(server: StartServer) -> None:
    url = server("garbage")
    r = reasoner(url)
    offered = candidates([5, 3, 8])
    selection, proposal, verdict = ask_all(r)
    assert selection.fallback and selection.label == GeometricReasoner().select_direction(GOAL, offered).label
    assert "fallback" in selection.note
    assert proposal == proposal.__class__(GOAL, fallback=True)
    assert verdict.judgement == "uncertain" and verdict.fallback
    assert outcomes(r) == ["fallback"] * 3
    stats = fake_stats(url)
    assert stats["chat_requests"] == 6  # question + one repair, three times
    repair = stats["bodies"][1]["messages"]
    assert [m["role"] for m in repair] == ["system", "user", "assistant", "user"]
    assert repair[2]["content"] == "I looked carefully, but I would rather not say."
    assert "no JSON object" in repair[3]["content"] and '"target_visible"' in repair[3]["content"]


def test_bad_then_good_is_repaired(server: StartServer) -> None:
    url = server("bad-then-good")
    r = reasoner(url)
    selection, proposal, verdict = ask_all(r)
    assert (selection.label, proposal.phrase, verdict.judgement) == (3, GOAL, "sure")
    assert outcomes(r) == ["repaired"] * 3
    assert fake_stats(url)["chat_requests"] == 6
    repair_message = fake_stats(url)["bodies"][1]["messages"][-1]["content"]
    assert '"direction" must be an integer direction label, got "left"' in repair_message


def test_server_errors_are_retried_then_fall_back(server: StartServer) -> None:
    url = server("error")
    r = reasoner(url, retries=2)
    selection = r.select_direction(GOAL, candidates([2, 4]))
    assert selection.fallback and selection.label in {2, 4} and "HTTP 500" in selection.note
    assert outcomes(r) == ["fallback"]
    assert fake_stats(url)["chat_requests"] == 3  # one attempt and two retries


def test_flaky_server_succeeds_after_retries(server: StartServer) -> None:
    url = server("flaky", fail_first=2)
    r = reasoner(url, retries=3)
    assert r.verify(GOAL, frame(1, 1), []).judgement == "sure"
    assert outcomes(r) == ["ok"]
    assert fake_stats(url)["chat_requests"] == 3


def test_retry_backoff_is_exponential(server: StartServer, caplog: pytest.LogCaptureFixture) -> None:
    url = server("error")
    r = reasoner(url, retries=2, backoff=0.1)
    with caplog.at_level(logging.INFO, logger="drivenav.semantics.openai_backend"):
        r.verify(GOAL, frame(1, 1), [])
    waits = [m.rsplit("retrying in ", 1)[1] for m in caplog.messages if "retrying in" in m]
    assert waits == ["0.10 s", "0.20 s"]  # doubling waits between the three tries
    assert fake_stats(url)["chat_requests"] == 3


def test_stall_times_out_then_falls_back_without_retrying(server: StartServer) -> None:
    url = server("stall", stall_s=20.0)
    r = reasoner(url, timeout=0.3, retries=3)
    verdict = r.verify(GOAL, frame(1, 1), [])
    assert verdict.judgement == "uncertain" and verdict.fallback
    assert fake_stats(url)["chat_requests"] == 1  # a timeout is not retried


def test_empty_choices_fall_back(server: StartServer) -> None:
    r = reasoner(server("empty"))
    proposal = r.propose_prompt(GOAL, view(1), "", [])
    assert proposal.fallback and proposal.phrase == GOAL and outcomes(r) == ["fallback"]


def test_dead_server_fails_check_connection_and_falls_back_mid_episode(server: StartServer) -> None:
    url, stop = start_fake_server("ok", lifetime=5.0)
    stop()
    r = reasoner(url, retries=1)
    with pytest.raises(InputError, match=re.escape(f"cannot reach the VLM server at {url}:")) as raised:
        r.check_connection(timeout=1.0)
    assert "--vlm-base-url" in str(raised.value) and "vLLM" in str(raised.value)
    selection = r.select_direction(GOAL, candidates([1, 2]))
    assert selection.fallback and "cannot connect" in selection.note


def test_check_connection_names_the_models_served(server: StartServer) -> None:
    url = server("ok")
    reasoner(url).check_connection()
    with pytest.raises(InputError, match=r"--vlm-model.*fake-vlm.*qwen"):
        OpenAIReasoner(url, "qwen").check_connection()
    with pytest.raises(InputError, match=r"HTTP 404.*under /v1"):
        OpenAIReasoner(url.removesuffix("/v1"), MODEL).check_connection()


def test_api_key_is_sent_as_bearer_token(server: StartServer, monkeypatch: pytest.MonkeyPatch) -> None:
    url = server("ok", api_key="s3cret")
    assert not reasoner(url, api_key="s3cret").verify(GOAL, frame(1, 1), []).fallback
    monkeypatch.setenv("DRIVENAV_VLM_API_KEY", "s3cret")
    from_env = reasoner(url)
    from_env.check_connection()
    assert not from_env.verify(GOAL, frame(1, 1), []).fallback
    assert fake_stats(url)["authorizations"] == ["Bearer s3cret", "Bearer s3cret"]


def test_rejected_api_key_is_not_retried(server: StartServer) -> None:
    url = server("ok", api_key="s3cret")
    r = reasoner(url, api_key="wrong", retries=3)
    verdict = r.verify(GOAL, frame(1, 1), [])
    assert verdict.fallback and fake_stats(url)["chat_requests"] == 1


def test_fake_server_command_line(tmp_path: Any) -> None:
    command = [sys.executable, "-m", "drivenav.semantics.fake_vlm_server", "--port", "0", "--lifetime", "20"]
    with subprocess.Popen(command, stdout=subprocess.PIPE, text=True) as process:
        try:
            assert process.stdout is not None
            url = process.stdout.readline().strip()
            r = reasoner(url)
            r.check_connection()
            recorder = RecordingReasoner(r, tmp_path / "answers.jsonl")
            assert recorder.select_direction(GOAL, candidates([4, 6])).label == 4
        finally:
            process.terminate()
            process.wait(timeout=10)


def test_invalid_settings_are_rejected() -> None:
    for url in ("localhost:8000/v1", "http://127.0.0.1:http/v1", "http:///v1"):
        with pytest.raises(InputError, match="--vlm-base-url"):
            OpenAIReasoner(url, MODEL)
    with pytest.raises(ValueError, match="max_images"):
        OpenAIReasoner("http://127.0.0.1:9/v1", MODEL, max_images=1)


def test_fallback_phrase_knows_no_vocabulary_and_skips_failed_prompts() -> None:
    assert fallback_phrase("couch", []) == "couch"
    assert fallback_phrase("couch", ["Couch"]) == "couch"  # no synonyms: any benchmark's categories work
    assert fallback_phrase("kitchen cabinet", ["Kitchen-Cabinet"]) == "cabinet"  # then the head noun
    assert fallback_phrase("kitchen cabinet", ["kitchen cabinet", "cabinet"]) == "kitchen cabinet"
    assert fallback_phrase("flux capacitor", ["flux capacitor"]) == "capacitor"


def test_first_json_object_is_extracted_from_prose_and_fences() -> None:
    text = 'Sure! {not json} here:\n```json\n{"judgement": "Sure ", "extra": {"a": 1}}\n```\nThen {"judgement": "not"}'
    assert extract_json_object(text) == {"judgement": "Sure ", "extra": {"a": 1}}
    assert parse_verdict(text).judgement == "sure"
    thinking = '<think>maybe {"judgement": "not"}?</think>{"judgement": "uncertain"}'
    assert parse_verdict(thinking).judgement == "uncertain"
    with pytest.raises(AnswerError, match="no JSON object"):
        extract_json_object("{" + "[" * 100_000)


@pytest.mark.parametrize(
    ("answer", "problem"),
    [
        ('{"direction": 9, "target_visible": false}', "not one of the offered directions [1, 2]"),
        ('{"direction": true, "target_visible": false}', '"direction" must be an integer'),
        ('{"direction": "1", "target_visible": false}', '"direction" must be an integer'),
        ('{"direction": 1, "target_visible": "no"}', '"target_visible" must be true or false'),
        ('{"direction": 1, "target_visible": true, "target_direction": null}', '"target_direction" must be'),
        ('{"direction": 1, "target_visible": false, "descriptions": {"7": "x"}}', 'key "7"'),
        ('{"direction": 1, "target_visible": false, "descriptions": {"1": 3}}', "must be a string"),
        ('{"direction": 1, "target_visible": false, "descriptions": ["x"]}', "must be an object"),
        ("[1, 2]", "no JSON object"),
    ],
)
def test_malformed_selections_are_explained(answer: str, problem: str) -> None:
    with pytest.raises(AnswerError, match=problem.replace("[", r"\[").replace("]", r"\]")):
        parse_selection(answer, {1, 2})


def test_selection_reports_the_target_direction_only_when_visible() -> None:
    seen = parse_selection('{"direction": 1, "target_visible": true, "target_direction": 2}', {1, 2})
    assert (seen.target_visible, seen.target_label) == (True, 2)
    unseen = parse_selection('{"direction": 1, "target_visible": false, "target_direction": 2}', {1, 2})
    assert unseen.target_label is None


@pytest.mark.parametrize(
    ("answer", "problem"),
    [
        ('{"phrase": "  "}', "non-empty"),
        ('{"phrase": 3}', "non-empty"),
        ('{"phrase": "a very tall old wooden dining chair"}', "7 words"),
        ('{"phrase": "Red  Chair"}', "already failed"),
    ],
)
def test_malformed_proposals_are_explained(answer: str, problem: str) -> None:
    with pytest.raises(AnswerError, match=problem):
        parse_proposal(answer, ["red chair"])


def test_verdict_must_be_one_of_three() -> None:
    with pytest.raises(AnswerError, match="must be one of"):
        parse_verdict('{"judgement": "probably"}')
    assert parse_proposal('{"phrase": " wooden   chair "}', []).phrase == "wooden chair"


# --- the floor question ---


def captions(body: dict[str, Any]) -> list[str]:
    """The texts after the question text: the images' captions."""
    return [part["text"] for part in user_parts(body) if part["type"] == "text"][1:]


@pytest.mark.parametrize("mode", ["ok", "fenced"])
def test_the_floor_prompt_names_the_floors_and_the_goal_and_carries_the_views(server: StartServer, mode: str) -> None:
    url = server(mode)
    r = reasoner(url)
    assert r.judge_floor(GOAL, floor_views(3)) == FloorJudgement(FAKE_FLOOR)
    assert [(c.kind, c.outcome) for c in r.calls] == [("judge_floor", "ok")] and r.calls[0].latency_ms > 0
    body = fake_stats(url)["bodies"][-1]
    assert body["messages"][0]["content"] == SYSTEM_PROMPT and body["max_tokens"] == 128
    text = user_parts(body)[0]["text"]
    assert text.startswith('Target object: "chair".') and text.endswith(FLOOR_SCHEMA)
    assert "a building of several floors" in text and "on this floor, on another floor, or" in text
    assert all(f'"{guess}"' in text for guess in FLOOR_GUESSES) and "not shown" not in text
    assert captions(body) == [
        "view 1 of this floor (step 15)",
        "view 2 of this floor (step 30)",
        "view 3 of this floor (step 45)",
    ]
    assert len(image_urls(body)) == 3


def test_the_floor_prompt_shows_the_latest_views_within_the_image_limit(server: StartServer) -> None:
    url = server("ok")
    reasoner(url, max_images=4).judge_floor(GOAL, floor_views(6))
    body = fake_stats(url)["bodies"][-1]
    assert (
        "(2 older views of this floor are not shown: only the latest fit in one request.)"
        in user_parts(body)[0]["text"]
    )
    assert captions(body) == [f"view {i} of this floor (step {15 * (i + 2)})" for i in range(1, 5)]
    assert len(image_urls(body)) == 4


def test_the_fake_server_answers_the_floor_question_the_same_each_time() -> None:
    question = [{"role": "user", "content": floor_text("bed", floor_views(2), 0)}]
    assert [json.loads(fake_answer("ok", question)) for _ in range(2)] == [{"floor": FAKE_FLOOR}] * 2


@pytest.mark.parametrize("guess", FLOOR_GUESSES)
def test_each_floor_guess_is_read(guess: FloorGuess) -> None:
    assert parse_floor(f'{{"floor": "{guess}"}}') == FloorJudgement(guess)
    assert parse_floor(f'Here:\n```json\n{{"floor": " {guess.upper()} "}}\n```').guess == guess


@pytest.mark.parametrize(
    ("answer", "problem"),
    [
        ('{"floor": "upstairs"}', '"floor" must be one of ["this", "other", "unsure"], got "upstairs"'),
        ('{"floor": 2}', "got 2"),
        ('{"judgement": "sure"}', "got null"),
        ("this floor", "no JSON object"),
    ],
)
def test_a_malformed_floor_answer_says_what_is_wrong(answer: str, problem: str) -> None:
    with pytest.raises(AnswerError, match=re.escape(problem)):
        parse_floor(answer)


def test_a_malformed_floor_answer_is_repaired(server: StartServer) -> None:
    url = server("bad-then-good")
    r = reasoner(url)
    assert r.judge_floor(GOAL, floor_views(2)) == FloorJudgement(FAKE_FLOOR)
    assert outcomes(r) == ["repaired"] and fake_stats(url)["chat_requests"] == 2
    repair = fake_stats(url)["bodies"][1]["messages"][-1]["content"]
    assert '"floor" must be one of ["this", "other", "unsure"], got "up"' in repair and repair.endswith(FLOOR_SCHEMA)


@pytest.mark.parametrize(("mode", "requests"), [("garbage", 2), ("error", 3), ("empty", 1)])
def test_a_hopeless_floor_answer_falls_back_to_unsure(server: StartServer, mode: str, requests: int) -> None:
    url = server(mode)
    r = reasoner(url)
    judgement = r.judge_floor(GOAL, floor_views(2))
    assert (judgement.guess, judgement.fallback) == ("unsure", True) and judgement.note.startswith("fallback (")
    assert [(c.kind, c.outcome) for c in r.calls] == [("judge_floor", "fallback")]
    assert fake_stats(url)["chat_requests"] == requests  # question and repair; three tries; one empty reply


def test_a_floor_without_views_is_unsure_without_a_request(server: StartServer) -> None:
    url = server("ok")
    r = reasoner(url)
    assert r.judge_floor(GOAL, []) == FloorJudgement("unsure", note="no views")
    assert [(c.kind, c.outcome) for c in r.calls] == [("judge_floor", "ok")]
    assert fake_stats(url)["chat_requests"] == 0
