"""A run directory that cannot be corrupted: records keyed by episode id (a duplicate or foreign record is refused
on resume, naming its line), no resume without run.json, readers that never write, trace names that no two ids
share and that stay short, records typed field by field, and no record lost to a failing trace or end of episode."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.agent.base import Agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode
from drivenav.errors import InputError, RunStoppedError
from drivenav.eval import rundir, runner
from drivenav.eval.episodes import episode_to_dict, load_episodes
from drivenav.eval.records import read_records
from drivenav.eval.rundir import EPISODES_FILE, RUN_FILE, RunDirectory, trace_path
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings

SCENES = "procedural:2"


def _spec(agent: str = "random") -> RunSpec:
    return RunSpec(EmbeddedSpec(SCENES, 0), load_settings(agent, options={"sim.max_steps": 15}))


def _episodes(count: int = 3) -> list[Episode]:
    return generate_episodes(SceneLibrary(SCENES, 0), count, 0)


@pytest.fixture
def finished(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A finished three-episode run of the random agent."""
    monkeypatch.setattr(runner, "_WORKER", None)
    evaluate(_episodes(), _spec(), tmp_path / "run", show_progress=False)
    return tmp_path / "run"


def _lines(run: Path) -> list[str]:
    return (run / EPISODES_FILE).read_text().splitlines(keepends=True)


def test_a_duplicated_record_is_refused_on_resume_naming_its_line(finished: Path) -> None:
    lines = _lines(finished)
    (finished / EPISODES_FILE).write_text("".join([*lines, lines[1]]))
    with pytest.raises(InputError, match=r"line 4.*second record of episode '1' \(the first is on line 2\)"):
        evaluate(_episodes(), _spec(), finished, show_progress=False)


def test_a_record_of_an_episode_outside_the_run_is_refused_naming_its_line(finished: Path) -> None:
    lines = _lines(finished)
    foreign = json.dumps({**json.loads(lines[0]), "episode_id": "99"}) + "\n"
    (finished / EPISODES_FILE).write_text("".join([*lines[:2], foreign]))
    with pytest.raises(InputError, match=r"line 3.*episode '99', which is not in this run"):
        evaluate(_episodes(), _spec(), finished, show_progress=False)


def test_compare_refuses_a_duplicated_record_in_one_line(finished: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = _lines(finished)
    (finished / EPISODES_FILE).write_text("".join([*lines, lines[0]]))
    assert main(["compare", str(finished), str(finished)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 4" in err and "one record per episode" in err


def test_resuming_records_without_run_json_is_refused(finished: Path) -> None:
    (finished / RUN_FILE).unlink()
    other = RunSpec(EmbeddedSpec(SCENES, 0), load_settings("oracle", options={"sim.max_steps": 99}))
    with pytest.raises(InputError, match=r"run\.json.*missing"):
        evaluate(_episodes(), other, finished, show_progress=False)
    assert len(read_records(finished / EPISODES_FILE)) == 3


def test_a_reader_never_cuts_a_line_a_live_run_is_writing(finished: Path) -> None:
    path = finished / EPISODES_FILE
    torn = path.read_bytes() + b'{"episode_id": "3", "agent'
    path.write_bytes(torn)
    assert len(read_records(path)) == 3
    assert path.read_bytes() == torn  # untouched: only the run's writer repairs it, under its lock
    with RunDirectory.open(finished, _spec().env, _spec().settings, _episodes()) as run:
        assert len(run.records()) == 3
    assert path.read_bytes() == torn[: torn.rfind(b"\n") + 1]


def test_trace_names_are_distinct_bounded_and_named_by_the_record(tmp_path: Path) -> None:
    ids = ["a/b", "a_b", "a_b~x", "..", "x" * 5_000_000, "ü", "7"]
    paths = [trace_path(tmp_path, i) for i in ids]
    assert len(set(paths)) == len(ids)
    assert all(len(p.name) <= 100 for p in paths)
    assert paths[1].name == "a_b.json" and paths[-1].name == "7.json"  # plain ids keep their names


def test_ids_that_once_shared_a_trace_get_their_own(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)
    episodes = [replace(e, episode_id=i) for e, i in zip(_episodes(3), ["a/b", "a_b", "y" * 1_000_000], strict=True)]
    evaluate(episodes, _spec(), tmp_path, show_progress=False)
    records = read_records(tmp_path / EPISODES_FILE)
    assert len(records) == 3 and len({r.trace for r in records}) == 3
    for record in records:
        trace = json.loads((tmp_path / record.trace).read_text())
        assert trace["episode_id"] == record.episode_id
        assert tmp_path / record.trace == trace_path(tmp_path, record.episode_id)


def test_a_trace_that_cannot_be_written_costs_no_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)
    monkeypatch.setattr(runner, "run_episode", _with_unserialisable_trace(runner.run_episode))
    evaluate(_episodes(2), _spec(), tmp_path, show_progress=False)
    records = read_records(tmp_path / EPISODES_FILE)
    assert len(records) == 2 and all(r.trace == "" and r.error == "" for r in records)


def _with_unserialisable_trace(run):  # type: ignore[no-untyped-def]
    def wrapped(*args, **kwargs):  # type: ignore[no-untyped-def]
        record, trace = run(*args, **kwargs)
        return record, replace(trace, step_ms={"bad": [object()]})

    return wrapped


class _EndsBadly(Agent):
    name = "ends-badly"

    def decide(self, observation):  # type: ignore[no-untyped-def]
        from drivenav.types import Action

        return Action.TURN_LEFT

    def end_episode(self) -> None:
        raise MemoryError("no room for the next episode's maps")


def test_a_failing_end_of_episode_never_replaces_the_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)
    monkeypatch.setattr(runner, "build_agent", lambda spec: _EndsBadly(spec.settings.sim))
    summary = evaluate(_episodes(2), _spec(), tmp_path, show_progress=False)
    assert summary.episodes == 2 and summary.errors == 0


@pytest.mark.parametrize(
    ("key", "value"), [("success", "yes"), ("steps", 1.5), ("spl", True), ("privileged", "semantic"), ("trace", 3)]
)
def test_a_record_of_the_wrong_type_names_its_line_and_field(finished: Path, key: str, value: object) -> None:
    lines = _lines(finished)
    lines[2] = json.dumps({**json.loads(lines[2]), key: value}) + "\n"
    (finished / EPISODES_FILE).write_text("".join(lines))
    with pytest.raises(InputError, match=rf"{EPISODES_FILE}:3: field 'record\.{key}'"):
        read_records(finished / EPISODES_FILE)


@pytest.mark.parametrize("damage", ["deleted", "garbage"])
def test_a_resume_repairs_the_runs_copy_of_its_episodes(finished: Path, damage: str) -> None:
    copy = finished / "episodes.json.gz"
    intact = copy.read_bytes()
    if damage == "deleted":
        copy.unlink()
    else:
        copy.write_bytes(b"\x1f\x8bnot gzip at all")
    evaluate(_episodes(), _spec(), finished, show_progress=False)
    assert copy.read_bytes() == intact


def test_a_copy_that_cannot_be_written_costs_no_record_and_a_resume_writes_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The episodes copy is written alongside the episodes: its failure (a full disk) is logged, the run goes on."""
    monkeypatch.setattr(runner, "_WORKER", None)

    def full_disk(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(rundir, "save_episodes", full_disk)
    evaluate(_episodes(), _spec(), tmp_path / "run", show_progress=False)
    assert len(read_records(tmp_path / "run" / EPISODES_FILE)) == 3
    assert not (tmp_path / "run" / "episodes.json.gz").exists()
    monkeypatch.undo()
    evaluate(_episodes(), _spec(), tmp_path / "run", show_progress=False)
    copy = load_episodes(tmp_path / "run" / "episodes.json.gz")
    assert [episode_to_dict(e) for e in copy] == [episode_to_dict(e) for e in _episodes()]


def test_no_record_is_written_without_run_json(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(runner, "_WORKER", None)

    def full_disk(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(rundir, "_write_run_file", full_disk)
    with pytest.raises(RunStoppedError, match=r"run.json could not be written.*No space left"):
        evaluate(_episodes(), _spec(), tmp_path / "run", show_progress=False)
    assert not (tmp_path / "run" / EPISODES_FILE).exists() or not (tmp_path / "run" / EPISODES_FILE).read_text()
