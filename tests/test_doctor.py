"""``drivenav doctor``: a table of checks with a fix under each failure, exit 1 if any failed; the VLM check
against a loopback OpenAI-compatible server (127.0.0.1, stopped after each test)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.doctor import DoctorRequest, run_checks, vlm_check
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import save_episodes
from drivenav.semantics.fake_vlm_server import fake_stats, start_fake_server
from drivenav.semantics.model_spec import ModelSpec


@pytest.fixture
def vlm(request: pytest.FixtureRequest) -> Iterator[str]:
    url, stop = start_fake_server(getattr(request, "param", "ok"), model="fake-vlm", lifetime=60.0)
    yield url
    stop()


def _doctor(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    code = main(["doctor", *argv])
    return code, capsys.readouterr().out


def test_a_vlm_answering_in_the_schema_passes(vlm: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out = _doctor(capsys, "--reasoner", "openai", "--vlm-base-url", vlm, "--vlm-model", "fake-vlm")
    assert code == 0, out
    assert "ok    VLM fake-vlm" in out and "one-image answer ok" in out
    stats = fake_stats(vlm)
    assert stats["chat_requests"] == 1
    body = stats["bodies"][-1]
    parts = [
        part for message in body["messages"] if isinstance(message["content"], list) for part in message["content"]
    ]
    images = [part for part in parts if part.get("type") == "image_url"]
    assert len(images) == 1 and images[0]["image_url"]["url"].startswith("data:image/jpeg;base64,")


@pytest.mark.parametrize("vlm", ["garbage", "error"], indirect=True)
def test_a_vlm_answering_out_of_schema_fails_with_its_fix(vlm: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out = _doctor(capsys, "--reasoner", "openai", "--vlm-base-url", vlm, "--vlm-model", "fake-vlm")
    assert code == 1
    assert "FAIL  VLM fake-vlm" in out and "fix:" in out


def test_an_unreachable_or_wrong_model_fails(vlm: str) -> None:
    wrong = vlm_check(ModelSpec(reasoner="openai", vlm_base_url=vlm, vlm_model="other-model"))
    assert not wrong.ok and "fake-vlm" in wrong.detail
    gone = vlm_check(ModelSpec(reasoner="openai", vlm_base_url="http://127.0.0.1:9/v1", vlm_model="m"))
    assert not gone.ok and "cannot reach" in gone.detail and gone.fix


def test_habitat_checks_without_habitat_installed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episodes = tmp_path / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural", 0), 3, 1), episodes)
    out_dir = tmp_path / "data" / "datasets" / "objectnav" / "mp3d" / "v1"
    assert (
        main(["episodes", "export", "--episodes", str(episodes), "--format", "objectnav-v1", "--out", str(out_dir)])
        == 0
    )
    capsys.readouterr()
    code, out = _doctor(capsys, "--env", "habitat", "--config", "mp3d", "--data-dir", str(tmp_path / "data"))
    assert code == 1
    lines = out.splitlines()
    assert any(line.startswith("FAIL  habitat-sim") for line in lines)
    assert "conda install habitat-sim" in out and "pip install habitat-lab==0.3.320260507" in out
    assert any("split val" in line and "3 episodes, 3 scenes, 0 scene files found" in line for line in lines)
    assert lines[-1].endswith("checks passed")


def test_only_what_was_asked_is_checked() -> None:
    checks = run_checks(DoctorRequest(ModelSpec()))
    assert [c.name for c in checks] == ["drivenav", "kernels"] and all(c.ok for c in checks)


def test_doctor_needs_a_benchmark_with_habitat(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["doctor", "--env", "habitat"]) == 2
    assert "--config" in capsys.readouterr().err
