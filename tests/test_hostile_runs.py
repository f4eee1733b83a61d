"""Hostile runs: locks, dead workers and drivers, signals, resumes with other settings, crashing agents, bad
options. Each answer is one line naming what and where (exit 2 for input, 1 for a dead worker), no traceback,
and no result is lost or duplicated."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pytest

from conftest import run_cli
from drivenav.agent.base import Agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.base import EpisodeMeasures
from drivenav.envs.embedded.env import EmbeddedEnv, EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.errors import InputError
from drivenav.eval import runner
from drivenav.eval.records import read_records
from drivenav.eval.report import format_table, summarize
from drivenav.eval.rundir import LOCK_FILE, RUN_FILE, RunDirectory
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.semantics.fake_vlm_server import start_fake_server
from drivenav.settings import load_settings
from drivenav.types import Action, Observation, SimConfig

SCENES = "procedural:2"
SLOW_RUN = ["--agent", "random", "--episodes", "6", "--seed", "1", "--max-steps", "400", "--workers", "2"]


def _spec(agent: str = "random", max_steps: int = 20) -> RunSpec:
    return RunSpec(EmbeddedSpec(SCENES, 0), load_settings(agent, options={"sim.max_steps": max_steps}))


def _episodes(count: int = 2) -> list:  # type: ignore[type-arg]
    return generate_episodes(SceneLibrary(SCENES, 0), count, 0)


def _one_line_error(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    for word in words:
        assert word in err, err
    return err


# ------------------------------------------------------------------------------------------------ the run dir


def test_a_second_evaluation_into_the_same_directory_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = _spec()
    with RunDirectory.open(tmp_path, spec.env, spec.settings, _episodes()):
        code = main(["eval", *SLOW_RUN[:2], "--episodes", "2", "--max-steps", "20", "--out", str(tmp_path)])
    assert code == 2
    _one_line_error(capsys, "--out", f"locked by pid {os.getpid()}")
    assert read_records(tmp_path / "episodes.jsonl") == []


def test_a_stale_lock_of_a_dead_process_is_taken_over(tmp_path: Path) -> None:
    (tmp_path / LOCK_FILE).write_text("999999999")
    summary = evaluate(_episodes(), _spec(), tmp_path, show_progress=False)
    assert summary.episodes == 2
    assert (tmp_path / LOCK_FILE).read_text() == str(os.getpid())


def test_resuming_with_other_settings_names_the_first_differing_key(tmp_path: Path) -> None:
    evaluate(_episodes(1), _spec(max_steps=20), tmp_path, show_progress=False)
    with pytest.raises(InputError, match=r"config\.sim\.max_steps"):
        evaluate(_episodes(1), _spec(max_steps=30), tmp_path, show_progress=False)
    with pytest.raises(InputError, match="'episodes'"):
        evaluate(_episodes(2), _spec(max_steps=20), tmp_path, show_progress=False)
    assert len(read_records(tmp_path / "episodes.jsonl")) == 1


def test_run_json_records_configuration_episodes_and_provenance(tmp_path: Path) -> None:
    evaluate(_episodes(1), _spec(), tmp_path, show_progress=False)
    run = json.loads((tmp_path / RUN_FILE).read_text())
    assert run["config"]["env"] == {"name": "embedded", "scenes": SCENES, "seed": 0}
    assert run["config"]["run"]["agent"] == "random" and run["config"]["sim"]["hfov_deg"] == 79.0
    assert run["config"]["paper"]["speed"]["lam"] == 0.65 and run["config"]["mapping"]["pixel_stride"] == 2
    assert len(run["episodes_sha256"]) == 64 and run["version"]
    assert set(run) >= {"git_commit", "git_dirty"}


@pytest.mark.parametrize(
    ("out", "expected"),
    [("file", "an existing file"), ("file/below", "a directory drivenav can create")],
)
def test_out_that_is_a_file_or_below_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], out: str, expected: str
) -> None:
    (tmp_path / "file").write_text("x")
    args = ["eval", "--agent", "random", "--episodes", "1", "--out", str(tmp_path / out)]
    assert main(args) == 2
    _one_line_error(capsys, "--out", expected)


@pytest.mark.parametrize(
    ("option", "value"),
    [("--seed", "-5"), ("--episodes", "1000000000000"), ("--episodes", "0"), ("--episodes", "\u00b2")],
)
def test_bad_numbers_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str
) -> None:
    args = {"--agent": "random", "--episodes": "1", "--out": str(tmp_path / "run"), option: value}
    assert main(["eval", *(item for pair in args.items() for item in pair)]) == 2
    _one_line_error(capsys, option, value)


# ------------------------------------------------------------------------------------------------ ground truth


@dataclass(frozen=True)
class _BlindSpec(EmbeddedSpec):
    """The embedded world pretending to have no ground truth (as a robot)."""

    name: ClassVar[str] = "blind"
    provides: ClassVar[frozenset[str]] = frozenset()


def test_an_agent_needing_ground_truth_the_world_lacks_is_refused_before_any_episode(tmp_path: Path) -> None:
    spec = RunSpec(_BlindSpec(SCENES, 0), load_settings("oracle"))
    with pytest.raises(InputError, match=r"blind world.*oracle, which needs geodesic"):
        evaluate(_episodes(), spec, tmp_path, show_progress=False)
    assert not (tmp_path / "episodes.jsonl").exists()


def test_ground_truth_only_for_agents_that_ask(tmp_path: Path) -> None:
    seen: list[Observation] = []

    class Watcher(Agent):
        name = "watcher"

        def decide(self, observation: Observation) -> Action:
            seen.append(observation)
            return Action.STOP

    env = EmbeddedEnv(SceneLibrary(SCENES, 0).load)
    record, _ = runner.run_episode(env, Watcher(SimConfig()), _episodes(1)[0], 0, 10)
    assert seen and all(o.semantic is None for o in seen)
    assert record.privileged == ()
    oracle = runner.build_agent(_spec("oracle"))
    record, _ = runner.run_episode(env, oracle, _episodes(1)[0], 0, 500)
    assert record.privileged == ("geodesic",) and record.success == 1


# ------------------------------------------------------------------------------------------------ crashes


class _Crashing(Agent):
    """Fails at its third step, like a model backend raising mid-episode."""

    name = "crashing"

    def decide(self, observation: Observation) -> Action:
        if observation.step == 2:
            raise ZeroDivisionError("model exploded")
        return Action.TURN_LEFT


def test_an_agent_exception_is_an_error_record_never_a_navigation_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    real: Callable[[RunSpec], Agent] = runner.build_agent
    monkeypatch.setattr(runner, "_WORKER", None)  # no worker of an earlier run in this process
    monkeypatch.setattr(
        runner, "build_agent", lambda spec: _Crashing(spec.settings.sim) if spec.agent == "random" else real(spec)
    )
    summary = evaluate(_episodes(), _spec("random"), tmp_path, show_progress=False)
    records = read_records(tmp_path / "episodes.jsonl")
    assert [(r.stop_reason, r.failure_cause, r.steps) for r in records] == [("error", "error", 2)] * 2
    assert records[0].error == "ZeroDivisionError: model exploded"
    trace = json.loads(next((tmp_path / "traces").iterdir()).read_text())
    assert trace["error"]["type"] == "ZeroDivisionError" and "decide" in trace["error"]["traceback"]
    assert summary.errors == 2 and summary.to_json()["errors"] == 2
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert warnings == [f"2 of 2 episodes ended in an error; tracebacks are under 'error' in {tmp_path / 'traces'}"]


def test_rates_over_no_episode_are_null(tmp_path: Path) -> None:
    summary = evaluate([], _spec(), tmp_path, show_progress=False)
    data = json.loads((tmp_path / "summary.json").read_text())
    assert summary.success_rate is None and data["success_rate"] is None and data["spl"] is None
    assert data["errors"] == 0 and data["vlm_fallbacks"] == 0


# ------------------------------------------------------------------------------------------------ processes


def _drivenav(out: Path, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    command = [sys.executable, "-m", "drivenav.cli", "eval", *args, "--out", str(out)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _children(pid: int) -> list[int]:
    """Pool workers of ``pid`` (not multiprocessing's resource tracker)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid and b"spawn_main" in cmdline:
            found.append(int(entry.name))
    return found


def _wait_for(condition: Callable[[], bool], limit: float = 60.0) -> bool:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return False


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _started(process: subprocess.Popen[str], workers: int = 2) -> list[int]:
    assert _wait_for(lambda: len(_children(process.pid)) == workers), "the pool never started"
    time.sleep(2.0)  # the workers are inside their first episodes
    return _children(process.pid)


def _finished_ids(out: Path) -> list[str]:
    return [r.episode_id for r in read_records(out / "episodes.jsonl")]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_a_killed_worker_names_its_episode_and_the_rerun_resumes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    process = _drivenav(out, *SLOW_RUN)
    victim = _started(process)[0]
    os.kill(victim, signal.SIGKILL)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 1
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and last.startswith("drivenav: error: the worker running episode ")
    assert "died (exit code -9)" in last and "rerun the same command to resume" in last
    finished = _finished_ids(out)
    assert len(finished) < 6
    assert main(["eval", *SLOW_RUN[:-2], "--out", str(out)]) == 0
    assert sorted(_finished_ids(out)) == sorted(str(i) for i in range(6))


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_workers_exit_by_themselves_when_the_driver_is_killed(tmp_path: Path) -> None:
    process = _drivenav(tmp_path / "run", *SLOW_RUN)
    workers = _started(process)
    process.kill()
    process.communicate(timeout=30)
    assert _wait_for(lambda: not any(_alive(pid) for pid in workers), limit=20.0)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_sigterm_behaves_like_ctrl_c(tmp_path: Path) -> None:
    out = tmp_path / "run"
    process = _drivenav(out, *SLOW_RUN)
    workers = _started(process)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130
    assert err.strip().splitlines()[-1] == "drivenav: interrupted (finished episodes are saved; rerun to resume)"
    assert "Traceback" not in err
    assert _wait_for(lambda: not any(_alive(pid) for pid in workers), limit=20.0)
    finished = _finished_ids(out)
    assert len(finished) == len(set(finished)) < 6


def test_a_resumed_run_says_so_and_its_bar_starts_where_it_stopped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = runner.run_all

    def two_then_interrupted(*args: object) -> Iterator[object]:
        for count, result in enumerate(real(*args), start=1):  # type: ignore[arg-type]
            yield result
            if count == 2:
                raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_all", two_then_interrupted)
    with pytest.raises(KeyboardInterrupt):
        evaluate(_episodes(3), _spec(max_steps=10), tmp_path)
    monkeypatch.setattr(runner, "run_all", real)
    capsys.readouterr()
    evaluate(_episodes(3), _spec(max_steps=10), tmp_path)
    err = capsys.readouterr().err
    assert "random (resuming)" in err and "2/3" in err and "0/3" not in err
    assert err.count("3/3") == 1  # the last bar line is drawn once
    assert len(_finished_ids(tmp_path)) == 3


def test_worker_warnings_reach_the_driver_and_stay_out_of_the_bar(tmp_path: Path) -> None:
    url, stop = start_fake_server("garbage", lifetime=300.0)
    try:
        models = ["--reasoner", "openai", "--vlm-base-url", url, "--vlm-model", "fake-vlm"]
        run = ["--scenes", "procedural:1", "--episodes", "2", "--seed", "3", "--max-steps", "40", "--workers", "2"]
        result = run_cli("eval", "--agent", "drive-nav", *run, *models, "--out", str(tmp_path / "run"))
    finally:
        stop()
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if "using the fallback answer" in line]
    assert warnings, result.stderr  # logged in the worker processes, printed by the driver
    assert all(line.split("\r")[-1].startswith("WARNING ") for line in warnings)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["vlm_fallbacks"] > 0 and summary["errors"] == 0


def test_a_world_without_ground_truth_reports_null_never_zero(tmp_path: Path) -> None:
    class Unmeasured(EmbeddedEnv):
        def measures(self) -> EpisodeMeasures:
            return EpisodeMeasures()  # a robot: no geodesics, no goal positions

    env = Unmeasured(SceneLibrary(SCENES, 0).load)
    record, _ = runner.run_episode(env, runner.build_agent(_spec("random")), _episodes(1)[0], 0, 10)
    data = record.to_json()
    assert [data[k] for k in ("success", "spl", "distance_to_goal", "path_length", "collisions")] == [None] * 5
    assert record.steps == 10 and record.failure_cause == "" and record.revisits == 0
    summary = summarize([record])
    assert summary.success_rate is None and summary.spl is None and summary.avg_steps == 10
    assert "n/a" in format_table(summary)
