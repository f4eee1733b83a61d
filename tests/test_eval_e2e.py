"""End-to-end evaluation in the embedded world: the oracle validates world, episodes and metrics together."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from conftest import REPO, run_cli, until_records
from drivenav.agent.body import ExplorerAgent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.eval.executor import Executor
from drivenav.eval.records import read_records
from drivenav.eval.runner import RunSpec, _Worker, build_agent, evaluate, run_episode
from drivenav.settings import load_settings

RECORD_KEYS = {
    "episode_id",
    "scene_id",
    "object_category",
    "success",
    "spl",
    "steps",
    "path_length",
    "geodesic_distance",
    "distance_to_goal",
    "revisits",
    "collisions",
    "stop_reason",
    "vlm_calls",
}
SUMMARY_KEYS = {"episodes", "success_rate", "spl", "avg_steps", "avg_revisits", "errors", "vlm_fallbacks"}


def _records(out: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]


def test_oracle_is_perfect_on_procedural_houses(tmp_path: Path) -> None:
    out = tmp_path / "oracle"
    result = run_cli(
        "eval",
        "--agent",
        "oracle",
        "--scenes",
        "procedural:3",
        "--episodes",
        "6",
        "--seed",
        "3",
        "--out",
        str(out),
    )
    assert result.returncode == 0, result.stderr
    assert "success rate" in result.stdout
    records = _records(out)
    assert len(records) == 6
    assert all(set(r) >= RECORD_KEYS for r in records)
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= SUMMARY_KEYS
    assert summary["success_rate"] == 1.0
    assert summary["spl"] >= 0.95
    assert all(r["revisits"] == 0 and r["stop_reason"] == "target_reached" for r in records)
    assert all(1.0 <= float(r["geodesic_distance"]) <= 30.0 for r in records)


def test_oracle_on_every_real_floor_plan(tmp_path: Path, maps_dir: Path) -> None:
    library = SceneLibrary(str(maps_dir))
    assert len(library.scene_ids) >= 9
    episodes = generate_episodes(library, len(library.scene_ids), seed=1)
    assert {e.scene_id for e in episodes} == set(library.scene_ids)
    spec = RunSpec(EmbeddedSpec(str(maps_dir), 1), load_settings("oracle", options={"run.seed": 1}))
    summary = evaluate(episodes, spec, tmp_path / "maps", show_progress=False)
    assert summary.success_rate == 1.0
    assert summary.spl is not None and summary.spl >= 0.95


def test_resume_skips_finished_and_workers_do_not_change_results(tmp_path: Path) -> None:
    episodes = generate_episodes(SceneLibrary("procedural:2", 5), 4, seed=5)
    spec = RunSpec(
        EmbeddedSpec("procedural:2", 5), load_settings("random", options={"run.seed": 5, "sim.max_steps": 40})
    )
    serial = tmp_path / "serial"
    evaluate(episodes, spec, serial, show_progress=False)
    lines = (serial / "episodes.jsonl").read_text().splitlines()
    (serial / "episodes.jsonl").write_text("\n".join(lines[:2]) + "\n")  # as if stopped after two episodes
    evaluate(episodes, spec, serial, show_progress=False)  # resumes: runs only the last two
    evaluate(episodes, spec, serial, show_progress=False)  # nothing left to do
    parallel = tmp_path / "parallel"
    evaluate(episodes, spec, parallel, Executor(workers=2), show_progress=False)
    first = sorted(read_records(serial / "episodes.jsonl"), key=lambda r: r.episode_id)
    second = sorted(read_records(parallel / "episodes.jsonl"), key=lambda r: r.episode_id)
    assert [r.episode_id for r in first] == ["0", "1", "2", "3"]
    assert first == second


def test_kill_minus_nine_loses_nothing_and_duplicates_nothing(tmp_path: Path) -> None:
    episodes_file = tmp_path / "eps.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural:2", 7), 6, seed=7), episodes_file)
    out = tmp_path / "run"
    args = [
        sys.executable,
        "-m",
        "drivenav.cli",
        "eval",
        "--agent",
        "random",
        "--scenes",
        "procedural:2",
        "--episodes",
        str(episodes_file),
        "--seed",
        "7",
        "--max-steps",
        "60",
        "--out",
        str(out),
    ]
    process = subprocess.Popen(args, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    results = out / "episodes.jsonl"
    until_records(process, results, 2)
    if process.poll() is None:
        os.kill(process.pid, signal.SIGKILL)
    process.wait()
    before = read_records(results)
    assert before, "the run wrote nothing before it was killed"
    with results.open("a") as handle:  # a torn line, as a kill during a write would leave
        handle.write('{"episode_id": "tor')
    result = run_cli(*[str(a) for a in args[3:]])
    assert result.returncode == 0, result.stderr
    after = read_records(results)
    ids = [r.episode_id for r in after]
    assert sorted(ids) == sorted({e.episode_id for e in load_episodes(episodes_file)})
    assert len(ids) == len(set(ids))
    assert all(r in after for r in before)


def test_episode_generation_is_deterministic_and_spread(tmp_path: Path) -> None:
    a, b = tmp_path / "a.json.gz", tmp_path / "b.json.gz"
    for path in (a, b):
        result = run_cli(
            "episodes",
            "generate",
            "--scenes",
            "procedural:4",
            "--num",
            "40",
            "--seed",
            "11",
            "--out",
            str(path),
        )
        assert result.returncode == 0, result.stderr
    assert a.read_bytes() == b.read_bytes()
    episodes = load_episodes(a)
    assert len(episodes) == 40
    assert len({e.scene_id for e in episodes}) == 4
    categories = {e.info["canonical_category"] for e in episodes}
    assert len(categories) >= 20
    synonyms = [e for e in episodes if e.info["synonym"]]
    assert 3 <= len(synonyms) <= 20
    assert all(e.object_category != e.info["canonical_category"] for e in synonyms)
    assert all(1.0 <= e.geodesic_distance <= 30.0 for e in episodes)


@pytest.mark.parametrize("agent", ["random"])
def test_other_agents_run_to_the_end(tmp_path: Path, agent: str) -> None:
    out = tmp_path / agent
    result = run_cli(
        "eval",
        "--agent",
        agent,
        "--scenes",
        "procedural:1",
        "--episodes",
        "1",
        "--max-steps",
        "30",
        "--out",
        str(out),
    )
    assert result.returncode == 0, result.stderr
    [record] = _records(out)
    assert record["steps"] == 30 and record["stop_reason"] == "timeout" and record["success"] == 0


def test_a_worker_releases_the_agents_maps_between_episodes_and_changes_no_record() -> None:
    """The runner's worker asks the agent to end each episode (its maps go before the next scene loads): the records
    are those of a fresh agent per episode."""
    episodes = generate_episodes(SceneLibrary("procedural:2", 5), 3, seed=5)
    spec = RunSpec(EmbeddedSpec("procedural:2", 5), load_settings("drive-nav", options={"run.seed": 5}))
    worker = _Worker(spec)
    for episode in episodes:
        record, _ = worker.run(episode)
        agent = worker.agent
        assert isinstance(agent, ExplorerAgent)
        assert agent.state is None  # its maps, directions pipeline and views with it
        fresh, _ = run_episode(worker.env, build_agent(spec), episode, spec.seed, spec.max_steps)
        assert replace(record, stats=fresh.stats) == fresh  # model latencies aside


def test_a_world_that_fails_the_workers_first_reset_gives_an_error_record(monkeypatch: pytest.MonkeyPatch) -> None:
    """The agent was never reset, yet ending the episode releases nothing it lacks: the failure is recorded as an
    error, not lost to the worker."""
    [episode] = generate_episodes(SceneLibrary("procedural:1", 5), 1, seed=5)
    worker = _Worker(RunSpec(EmbeddedSpec("procedural:1", 5), load_settings("drive-nav", options={"run.seed": 5})))

    def broken_reset(_: object) -> None:
        raise RuntimeError("the world is gone")

    monkeypatch.setattr(worker.env, "reset", broken_reset)
    record, _ = worker.run(episode)
    assert record.stop_reason == "error" and record.steps == 0
