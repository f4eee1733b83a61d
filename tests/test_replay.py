"""Recording a reasoner's and a scorer's answers and replaying them (drivenav.semantics.replay)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError
from drivenav.semantics.embedded_scorer import EmbeddedScorer
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.fake_vlm_server import fake_stats, start_fake_server
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import (
    Candidate,
    FloorJudgement,
    Judgement,
    ModelCall,
    Proposal,
    Selection,
    Verdict,
    VerificationFrame,
    View,
)
from drivenav.semantics.registry import check_models, make_reasoner, make_scorer
from drivenav.semantics.replay import (
    RecordingReasoner,
    RecordingScorer,
    ReplayMissError,
    ReplayReasoner,
    ReplayScorer,
    floor_request,
    score_request,
    select_request,
)
from drivenav.types import GroundTruth
from frames import observation_of
from test_openai_backend import GOAL, ask_all, candidates, floor_views, frame, image, reasoner, view


class ScriptedReasoner(GeometricReasoner):
    """Answers verification with a scripted sequence, so repeated questions get different answers."""

    name = "scripted"

    def __init__(self, judgements: Sequence[Judgement]) -> None:
        super().__init__()
        self.judgements = list(judgements)

    def begin_episode(self, goal: str, truth: GroundTruth | None) -> None:
        super().begin_episode(goal, truth)
        self.calls.append(ModelCall("begin", 0.0, "ok"))

    def verify(self, goal: str, frame: VerificationFrame, earlier: Sequence[VerificationFrame]) -> Verdict:
        self.calls.append(ModelCall("verify", 0.0, "ok"))
        judgement = self.judgements.pop(0)
        return Verdict(judgement, fallback=judgement == "uncertain")


def test_replay_reproduces_a_recorded_openai_run_without_the_server(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    url, stop = start_fake_server("bad-then-good", lifetime=30.0)
    recorder = RecordingReasoner(reasoner(url), path)
    recorder.begin_episode(GOAL, None)
    recorded = [*ask_all(recorder), recorder.select_direction(GOAL, candidates([9, 12]))]
    assert recorder.name == "openai" and [c.outcome for c in recorder.calls] == ["repaired"] * 4
    requests_while_recording = fake_stats(url)["chat_requests"]
    stop()

    replay = ReplayReasoner(path)
    replay.begin_episode(GOAL, None)
    replayed = [*ask_all(replay), replay.select_direction(GOAL, candidates([9, 12]))]
    assert replayed == recorded
    assert replay.name == "replay" and [c.outcome for c in replay.calls] == ["replayed"] * 4
    assert requests_while_recording == 8 and len(path.read_text().splitlines()) == 4


def test_each_answer_is_written_as_soon_as_it_is_given(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    recorder = RecordingReasoner(GeometricReasoner(), path)
    recorder.select_direction(GOAL, candidates([1, 2]))
    record = json.loads(path.read_text())
    assert record["kind"] == "select_direction" and record["goal"] == GOAL
    assert record["key"] == select_request(GOAL, candidates([1, 2])).key
    assert record["answer"]["label"] == 1 and "[1, 2]" in record["summary"]


def test_a_changed_input_misses_with_a_clear_message(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    recorder = RecordingReasoner(GeometricReasoner(), path)
    offered = candidates([1, 2])
    recorder.select_direction(GOAL, offered)
    recorder.propose_prompt(GOAL, view(1), "a hallway", ["seat"])
    replay = ReplayReasoner(path)
    nudged = [replace(offered[0], bearing=offered[0].bearing + 1e-9), offered[1]]
    assert replay.select_direction(GOAL, nudged).label == 1  # below the rounding: still a hit
    moved = [replace(offered[0], travel_time=7.5), offered[1]]
    with pytest.raises(ReplayMissError) as missed:
        replay.select_direction(GOAL, moved)
    message = str(missed.value)
    assert isinstance(missed.value, InputError) and str(path) in message
    assert "select_direction" in message and repr(GOAL) in message and "candidate labels [1, 2]" in message
    assert select_request(GOAL, moved).key[:16] in message and "holds 1 select_direction answers" in message
    repainted = view(1)
    repainted.rgb[0, 0, 0] ^= 1
    with pytest.raises(ReplayMissError, match="propose_prompt"):
        replay.propose_prompt(GOAL, repainted, "a hallway", ["seat"])
    with pytest.raises(ReplayMissError, match="holds 0 propose_prompt answers for that goal"):
        replay.propose_prompt("sofa", view(1), "a hallway", ["seat"])


def test_repeated_questions_replay_in_recorded_order(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    recorder = RecordingReasoner(ScriptedReasoner(["uncertain", "sure"]), path)
    recorder.begin_episode(GOAL, None)
    assert recorder.calls[0].kind == "begin"  # passed through to the inner reasoner
    first, second = (recorder.verify(GOAL, frame(1, 4), []) for _ in range(2))
    replay = ReplayReasoner(path)
    assert [replay.verify(GOAL, frame(1, 4), []) for _ in range(3)] == [first, second, second]
    assert first == Verdict("uncertain", fallback=True) and second.judgement == "sure"


def test_every_answer_field_survives_the_round_trip(tmp_path: Path) -> None:
    selection = Selection(3, True, 5, {3: "a kitchen", 5: "a chair by the window"}, fallback=True, note="n")
    proposal = Proposal("wooden chair", fallback=True)

    class Fixed(GeometricReasoner):
        def select_direction(self, goal: str, offered: Sequence[Candidate]) -> Selection:
            return selection

        def propose_prompt(self, goal: str, view: View, description: str, failed: Sequence[str]) -> Proposal:
            return proposal

    path = tmp_path / "run.jsonl"
    recorder = RecordingReasoner(Fixed(), path)
    recorder.select_direction(GOAL, candidates([3, 5]))
    recorder.propose_prompt(GOAL, view(3), "", [])
    replay = ReplayReasoner(path)
    assert replay.select_direction(GOAL, candidates([3, 5])) == selection
    assert replay.propose_prompt(GOAL, view(3), "", []) == proposal


def test_unusable_replay_files_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="readable replay file"):
        ReplayReasoner(tmp_path / "missing.jsonl")
    path = tmp_path / "bad.jsonl"
    good = {
        "key": "k",
        "kind": "verify",
        "goal": GOAL,
        "summary": "",
        "answer": {"judgement": "not", "fallback": False},
    }
    bad = good | {"answer": {"judgement": "maybe", "fallback": False}}
    path.write_text(json.dumps(good) + "\n\n" + json.dumps(bad) + "\n")
    with pytest.raises(InputError, match=r"field 'line 3: answer\.judgement': expected sure or uncertain or not"):
        ReplayReasoner(path)
    selection = {"label": "two", "target_visible": False, "target_label": None, "descriptions": {}, "note": ""}
    wrong = good | {"kind": "select_direction", "answer": selection | {"fallback": False}}
    path.write_text(json.dumps(wrong) + "\n")
    with pytest.raises(
        InputError, match=r"field 'line 1: answer\.label': expected a direction label or null, got 'two'"
    ):
        ReplayReasoner(path)
    path.write_bytes(b"\xff\xfe not text")
    with pytest.raises(InputError, match="expected a UTF-8 text file written with --vlm-record"):
        ReplayReasoner(path)


# --- the floor question's answers ---


class ScriptedFloors(GeometricReasoner):
    """Answers the floor question with a scripted sequence (every field of a judgement set somewhere)."""

    def __init__(self, judgements: Sequence[FloorJudgement]) -> None:
        super().__init__()
        self.judgements = list(judgements)

    def judge_floor(self, goal: str, views: Sequence[View]) -> FloorJudgement:
        self.calls.append(ModelCall("judge_floor", 0.0, "ok"))
        return self.judgements.pop(0)


def test_floor_answers_replay_exactly_from_a_recorded_openai_run(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    albums = [floor_views(2), floor_views(3, first=4), floor_views(2)]
    url, stop = start_fake_server("bad-then-good", lifetime=30.0)
    recorder = RecordingReasoner(reasoner(url), path)
    recorder.begin_episode(GOAL, None)
    recorded = [recorder.judge_floor(GOAL, album) for album in albums]
    assert [(c.kind, c.outcome) for c in recorder.calls] == [("judge_floor", "repaired")] * 3
    stop()
    record = json.loads(path.read_text().splitlines()[0])
    assert record["kind"] == "judge_floor" and record["key"] == floor_request(GOAL, albums[0]).key
    assert record["answer"] == {"guess": "other", "fallback": False, "note": ""}
    assert record["summary"] == "views of steps [15, 30]"

    replay = ReplayReasoner(path)
    replay.begin_episode(GOAL, None)
    assert [replay.judge_floor(GOAL, album) for album in albums] == recorded
    assert [(c.kind, c.outcome) for c in replay.calls] == [("judge_floor", "replayed")] * 3


def test_every_floor_answer_replays_in_recorded_order(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    answers = [FloorJudgement("this"), FloorJudgement("other", note="no bedroom"), FloorJudgement("unsure", True, "x")]
    recorder = RecordingReasoner(ScriptedFloors(answers), path)
    recorded = [recorder.judge_floor(GOAL, floor_views(2)) for _ in answers]
    assert recorded == answers
    replay = ReplayReasoner(path)
    assert [replay.judge_floor(GOAL, floor_views(2)) for _ in range(4)] == [*answers, answers[-1]]


def test_a_floor_question_not_recorded_misses_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    RecordingReasoner(ScriptedFloors([FloorJudgement("this")]), path).judge_floor(GOAL, floor_views(2))
    replay = ReplayReasoner(path)
    repainted = floor_views(2)
    repainted[1].rgb[0, 0, 0] ^= 1
    for views in (repainted, floor_views(1)):
        with pytest.raises(ReplayMissError) as missed:
            replay.judge_floor(GOAL, views)
        message = str(missed.value)
        assert "\n" not in message and str(path) in message and "judge_floor question with goal 'chair'" in message
        assert floor_request(GOAL, views).key[:16] in message and "holds 1 judge_floor answers for that goal" in message
    with pytest.raises(ReplayMissError, match="holds 0 judge_floor answers for that goal"):
        replay.judge_floor("bed", floor_views(2))


def test_a_recording_without_floor_answers_still_reads_and_misses_them(tmp_path: Path) -> None:
    """A file written before the floor question (no judge_floor kind) replays its questions as it did."""
    path = tmp_path / "old.jsonl"
    verdict = RecordingReasoner(ScriptedReasoner(["sure"]), path).verify(GOAL, frame(1, 4), [])
    replay = ReplayReasoner(path)
    assert replay.verify(GOAL, frame(1, 4), []) == verdict
    with pytest.raises(ReplayMissError, match=r"judge_floor question .*views of steps \[15, 30\].*holds 0"):
        replay.judge_floor(GOAL, floor_views(2))


@pytest.mark.parametrize(
    ("answer", "problem"),
    [
        ({"guess": "upstairs", "fallback": False, "note": ""}, r"answer\.guess': expected this or other or unsure"),
        (
            {"guess": "This", "fallback": False, "note": ""},
            r"answer\.guess': expected this or other or unsure, got 'This'",
        ),
        ({"guess": "this", "fallback": False}, r"answer\.note': expected a text"),
        ({"guess": "this", "note": ""}, r"answer\.fallback': expected true or false"),
    ],
)
def test_a_recorded_floor_answer_that_is_no_guess_is_refused(tmp_path: Path, answer: object, problem: str) -> None:
    path = tmp_path / "edited.jsonl"
    record = {"key": "k", "kind": "judge_floor", "goal": GOAL, "summary": "", "answer": answer}
    path.write_text(json.dumps(record) + "\n")
    with pytest.raises(InputError, match="field 'line 1: " + problem):
        ReplayReasoner(path)


# --- the image-text scorer's answers ---

SCORED = GroundTruth({1: "chair", 2: "armchair", 3: "toilet"}, VOCABULARY)


def instances(seed: int) -> np.ndarray:
    """A 48 x 64 instance image: a chair, an armchair and a toilet in rows of a seed-dependent height."""
    rows = np.random.default_rng(seed).integers(1, 4, size=(48, 1))
    return np.repeat(rows, 64, axis=1).astype(np.int32)


def scored_frames() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Goal, RGB and instance image of each question; the third repeats the first."""
    return [(GOAL, image(1), instances(1)), ("toilet", image(2), instances(2)), (GOAL, image(1), instances(1))]


def test_scores_replay_exactly_from_the_reasoners_recording(tmp_path: Path) -> None:
    """Reasoner and scorer record into one file; each replay answers its own kinds from it."""
    path = tmp_path / "run.jsonl"
    scorer = RecordingScorer(EmbeddedScorer(default_embedder()), path)
    scorer.begin_episode(SCORED)
    recorded = [scorer.score(goal, observation_of(rgb, labels)) for goal, rgb, labels in scored_frames()]
    selection = RecordingReasoner(GeometricReasoner(), path).select_direction(GOAL, candidates([1, 2]))
    assert scorer.name == "embedded" and [c.outcome for c in scorer.calls] == ["ok"] * 3
    assert recorded[0] == recorded[2] and len(set(recorded)) == 2 and all(0.0 < s < 1.0 for s in recorded)
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert [line["kind"] for line in lines] == ["score"] * 3 + ["select_direction"]
    assert lines[0]["answer"] == {"score": recorded[0]} and lines[0]["key"] == score_request(GOAL, image(1)).key

    replay = ReplayScorer(path)
    replay.begin_episode(None)
    assert [replay.score(goal, observation_of(rgb)) for goal, rgb, _ in scored_frames()] == recorded  # exact floats
    assert replay.name == "replay" and [(c.kind, c.outcome) for c in replay.calls] == [("score", "replayed")] * 3
    assert ReplayReasoner(path).select_direction(GOAL, candidates([1, 2])) == selection


def test_a_score_not_in_the_recording_misses_with_a_clear_message(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    RecordingScorer(EmbeddedScorer(default_embedder()), path).score(GOAL, observation_of(image(1), instances(1)))
    replay = ReplayScorer(path)
    repainted = image(1)
    repainted[0, 0, 0] ^= 1
    with pytest.raises(ReplayMissError) as missed:
        replay.score(GOAL, observation_of(repainted, instances(1)))
    message = str(missed.value)
    assert (
        str(path) in message and "score question with goal 'chair'" in message and "frame of shape 48x64x3" in message
    )
    assert "holds 1 score answers for that goal" in message
    with pytest.raises(ReplayMissError, match="holds 0 score answers for that goal"):
        replay.score("toilet", observation_of(image(1)))
    with pytest.raises(ReplayMissError, match="holds 0 select_direction answers"):
        ReplayReasoner(path).select_direction(GOAL, candidates([1]))


def test_a_malformed_score_is_an_input_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonl"
    record = {"key": "k", "kind": "score", "goal": GOAL, "summary": "", "answer": {"score": "high"}}
    path.write_text(json.dumps(record) + "\n")
    with pytest.raises(
        InputError, match=r"field 'line 1: answer\.score': expected a finite similarity in \[-1, 1\], got 'high'"
    ):
        ReplayScorer(path)
    with pytest.raises(InputError, match=r"answer\.score"):  # the reasoner's replay reads the same file
        ReplayReasoner(path)


@pytest.mark.parametrize("score", ["NaN", "Infinity", "-Infinity", "1e308", "-2.5"])
def test_a_replayed_score_no_scorer_gives_is_refused(tmp_path: Path, score: str) -> None:
    """Every scorer's similarity lies in [-1, 1] and a non-finite one is recorded as 0: a NaN or 1e308 in a
    replay file was fused into the value map without a word."""
    path = tmp_path / "edited.jsonl"
    record = json.dumps({"key": "k", "kind": "score", "goal": GOAL, "summary": "", "answer": {"score": 0.0}})
    path.write_text(record.replace('"score": 0.0', f'"score": {score}') + "\n")
    expected = r"field 'line 1: answer\.score': expected a finite similarity in \[-1, 1\]"
    with pytest.raises(InputError, match=expected):
        ReplayScorer(path)


def test_a_replayed_cosine_rounded_past_one_is_kept(tmp_path: Path) -> None:
    path = tmp_path / "calls.jsonl"
    path.write_text(
        json.dumps({"key": "k", "kind": "score", "goal": GOAL, "summary": "", "answer": {"score": 1.0000001}})
    )
    ReplayScorer(path)  # a float32 cosine of two unit vectors


def test_the_registry_records_and_replays_scores_through_one_file(tmp_path: Path) -> None:
    path = tmp_path / "calls.jsonl"
    recorder = make_scorer(ModelSpec(vlm_record=str(path)))
    assert isinstance(recorder, RecordingScorer) and isinstance(
        make_reasoner(ModelSpec(vlm_record=str(path))), RecordingReasoner
    )
    recorder.begin_episode(SCORED)
    value = recorder.score(GOAL, observation_of(image(3), instances(3)))
    spec = ModelSpec(scorer="replay", vlm_replay=str(path))
    check_models(spec)  # the embedded reasoner reads no recording; the scorer's replay reads it
    assert make_scorer(spec).score(GOAL, observation_of(image(3))) == value
    with pytest.raises(InputError, match="--vlm-replay"):
        check_models(ModelSpec(scorer="replay", vlm_replay=str(tmp_path / "missing.jsonl")))
