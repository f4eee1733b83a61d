"""Recording a reasoner's answers and replaying them (drivenav.semantics.replay)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.errors import InputError
from drivenav.semantics.fake_vlm_server import fake_stats, start_fake_server
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.protocols import (
    Candidate,
    Judgement,
    ModelCall,
    Proposal,
    Selection,
    Verdict,
    VerificationFrame,
    View,
)
from drivenav.semantics.replay import RecordingReasoner, ReplayMissError, ReplayReasoner, select_request
from drivenav.types import GroundTruth
from test_openai_backend import GOAL, ask_all, candidates, frame, reasoner, view


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
