"""Hostile model options: each is refused before any episode with one line naming the option and what is wrong."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import pytest

from drivenav.cli import main

RUN = ["eval", "--agent", "drive-nav", "--episodes", "1", "--max-steps", "5"]


def _refused(capsys: pytest.CaptureFixture[str], args: list[str], *words: str) -> None:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err


def test_vlm_record_naming_a_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    _refused(capsys, [*RUN, "--out", str(out), "--vlm-record", str(tmp_path)], "--vlm-record", "a directory")
    assert not (out / "episodes.jsonl").exists()  # nothing ran, so nothing a rerun would take as finished


def test_vlm_record_in_a_folder_that_does_not_exist(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "missing" / "calls.jsonl"
    _refused(capsys, [*RUN, "--out", str(tmp_path / "run"), "--vlm-record", str(record)], "--vlm-record", "writable")


@pytest.mark.parametrize("detector", ["sam3", "owlv2"])
def test_detector_without_the_models_extra_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, detector: str
) -> None:
    monkeypatch.setitem(sys.modules, "transformers", None)  # as if the extra were not installed
    args = [*RUN, "--out", str(tmp_path / "run"), "--detector", detector]
    _refused(capsys, args, "--detector", "pip install 'drivenav[models]'", "transformers not installed")


def test_replay_file_that_is_not_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    replay = tmp_path / "calls.jsonl"
    replay.write_bytes(b'{"key": "\xff\xfe"}\n')
    args = [*RUN, "--out", str(tmp_path / "run"), "--reasoner", "replay", "--vlm-replay", str(replay)]
    _refused(capsys, args, str(replay), "UTF-8")


def test_replay_record_with_an_invalid_answer_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    replay = tmp_path / "calls.jsonl"
    answer = '{"judgement": "sure", "fallback": "no"}'
    replay.write_text('{"key": "k", "kind": "verify", "goal": "chair", "summary": "", "answer": ' + answer + "}\n")
    args = [*RUN, "--out", str(tmp_path / "run"), "--reasoner", "replay", "--vlm-replay", str(replay)]
    _refused(capsys, args, "line 1: answer.fallback", "true or false", "'no'")


def test_detector_with_an_outdated_transformers_says_what_is_missing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "transformers", ModuleType("transformers"))  # installed, but without SAM3
    args = [*RUN, "--out", str(tmp_path / "run"), "--detector", "sam3"]
    _refused(capsys, args, "--detector", "pip install 'drivenav[models]'", "cannot import name 'Sam3Model'")
