"""The semantic loop from the command line: real HTTP reasoner on loopback, record/replay, clear model errors."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from conftest import run_cli
from drivenav.semantics.fake_vlm_server import start_fake_server

EPISODE_ARGS = ["--scenes", "procedural:1", "--episodes", "2", "--seed", "3", "--max-steps", "60"]
TIMING_KEYS = {"vlm_latency_ms"}


def _records(out: Path) -> list[dict[str, object]]:
    rows = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    return sorted(rows, key=lambda r: str(r["episode_id"]))


def _without_timing(record: dict[str, object]) -> dict[str, object]:
    return {k: v for k, v in record.items() if k not in TIMING_KEYS}


def _replay(
    recording: Path, out: Path, agent: str = "drive-nav", role: str = "--reasoner"
) -> subprocess.CompletedProcess[str]:
    """``drivenav eval`` answering every question of ``role`` (the reasoner's, or the scorer's) from ``recording``."""
    return run_cli(
        "eval", "--agent", agent, *EPISODE_ARGS, role, "replay", "--vlm-replay", str(recording), "--out", str(out)
    )


def _recorded(recording: Path, out: Path, agent: str) -> None:
    """``drivenav eval`` with the default models, recording their answers to ``recording``."""
    first = run_cli("eval", "--agent", agent, *EPISODE_ARGS, "--vlm-record", str(recording), "--out", str(out))
    assert first.returncode == 0, first.stderr
    assert recording.stat().st_size > 0


def _replayed_exactly(tmp_path: Path) -> list[dict[str, object]]:
    """The replayed run's records equal the recorded run's (timings aside) and every episode took the recorded
    actions; the recorded records."""
    recorded, replayed = _records(tmp_path / "recorded"), _records(tmp_path / "replayed")
    assert [_without_timing(r) for r in recorded] == [_without_timing(r) for r in replayed]
    for record in recorded:
        trace_a = json.loads((tmp_path / "recorded" / "traces" / f"{record['episode_id']}.json").read_text())
        trace_b = json.loads((tmp_path / "replayed" / "traces" / f"{record['episode_id']}.json").read_text())
        assert trace_a["actions"] == trace_b["actions"]
    return recorded


def test_replay_reproduces_a_recorded_run_exactly(tmp_path: Path) -> None:
    """drive-nav's reasoner answers replay exactly; it builds no image-text scorer (the target check is off)."""
    recording = tmp_path / "vlm.jsonl"
    _recorded(recording, tmp_path / "recorded", "drive-nav")
    second = _replay(recording, tmp_path / "replayed")
    assert second.returncode == 0, second.stderr
    recorded = _replayed_exactly(tmp_path)
    assert all("score" not in r["vlm_calls_by_kind"] for r in recorded)  # type: ignore[operator]


def test_vlfm_replays_its_scores_exactly(tmp_path: Path) -> None:
    """VLFM's image-text scores, recorded with ``--vlm-record`` and answered by ``--scorer replay``: the same
    records (one score per step) and actions."""
    recording = tmp_path / "scores.jsonl"
    _recorded(recording, tmp_path / "recorded", "vlfm")
    replay = _replay(recording, tmp_path / "replayed", "vlfm", "--scorer")
    assert replay.returncode == 0, replay.stderr
    recorded = _replayed_exactly(tmp_path)
    assert all(r["vlm_calls_by_kind"] == {"score": r["steps"]} for r in recorded)


def _replayed_from_one_file(tmp_path: Path, agent: str) -> tuple[list[dict[str, object]], set[str]]:
    """``agent``'s reasoner answers and image-text scores recorded into one file with ``--vlm-record``, then both
    answered from it: the same records and actions. The recorded records and the kinds of the recorded calls."""
    recording = tmp_path / "calls.jsonl"
    _recorded(recording, tmp_path / "recorded", agent)
    both = ["--reasoner", "replay", "--scorer", "replay", "--vlm-replay", str(recording)]
    replay = run_cli("eval", "--agent", agent, *EPISODE_ARGS, *both, "--out", str(tmp_path / "replayed"))
    assert replay.returncode == 0, replay.stderr
    recorded = _replayed_exactly(tmp_path)
    return recorded, {json.loads(line)["kind"] for line in recording.read_text().splitlines()}


def test_apexnav_replays_its_category_answers_and_scores_exactly(tmp_path: Path) -> None:
    """ApexNav's category question (the reasoner's) and its image-text scores (the scorer's, one per step)."""
    recorded, kinds = _replayed_from_one_file(tmp_path, "apexnav")
    assert all(r["vlm_calls_by_kind"] == {"category_hints": 1, "score": r["steps"]} for r in recorded)
    assert kinds == {"category_hints", "score"}


def test_drive_nav_plus_replays_its_target_checks_exactly(tmp_path: Path) -> None:
    """drive-nav-plus's target check (beyond the paper) scores each new representative view, not every frame; its
    scores and the reasoner's choices replay from one file."""
    recorded, kinds = _replayed_from_one_file(tmp_path, "drive-nav-plus")
    assert all(0 < r["vlm_calls_by_kind"]["score"] < r["steps"] for r in recorded)  # type: ignore[index]
    assert kinds >= {"score", "select_direction"}


def _eval_against_fake_server(tmp_path: Path, mode: str) -> list[dict[str, object]]:
    """Run two short episodes with the ``openai`` reasoner against a loopback server in ``mode``."""
    url, stop = start_fake_server(mode, lifetime=120.0)
    try:
        args = ["--reasoner", "openai", "--vlm-base-url", url, "--vlm-model", "fake-vlm"]
        result = run_cli("eval", "--agent", "drive-nav", *EPISODE_ARGS, *args, "--out", str(tmp_path / "run"))
    finally:
        stop()
    assert result.returncode == 0, result.stderr
    records = _records(tmp_path / "run")
    assert all(r["error"] == "" for r in records)
    return records


def test_openai_reasoner_against_a_loopback_server(tmp_path: Path) -> None:
    records = _eval_against_fake_server(tmp_path, "ok")
    assert all(int(r["vlm_calls"]) > 0 for r in records)  # type: ignore[call-overload]
    assert sum(int(r["vlm_fallbacks"]) for r in records) == 0  # type: ignore[call-overload]


def test_garbage_answers_fall_back_without_crashing(tmp_path: Path) -> None:
    records = _eval_against_fake_server(tmp_path, "garbage")
    assert sum(int(r["vlm_fallbacks"]) for r in records) > 0  # type: ignore[call-overload]


def test_unreachable_vlm_server_is_a_clear_error(tmp_path: Path) -> None:
    url, stop = start_fake_server("ok")
    stop()  # nothing listens there any more
    result = run_cli(
        "eval",
        "--agent",
        "drive-nav",
        *EPISODE_ARGS,
        "--reasoner",
        "openai",
        "--vlm-base-url",
        url,
        "--out",
        str(tmp_path / "run"),
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "--vlm-base-url" in result.stderr and url in result.stderr


def test_unknown_backend_names(tmp_path: Path) -> None:
    for option, value in (("--reasoner", "gpt-9"), ("--detector", "x-ray")):
        result = run_cli("eval", "--agent", "drive-nav", *EPISODE_ARGS, option, value, "--out", str(tmp_path / "r"))
        assert result.returncode == 2 and option in result.stderr and "Traceback" not in result.stderr


def test_replay_miss_names_the_request(tmp_path: Path) -> None:
    recording = tmp_path / "empty.jsonl"
    recording.write_text("")
    result = _replay(recording, tmp_path / "run")
    assert result.returncode == 2, result.stderr
    assert "select_direction" in result.stderr and "Traceback" not in result.stderr
