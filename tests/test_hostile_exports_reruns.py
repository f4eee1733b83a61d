"""Hostile cases of issue 60: an ``episodes export`` is written whole into its own folder or refused, and its ids
stay unique within a scene; a rerun runs again the episodes that failed to start (their records moved aside, said
in one line) while errors after a finished episode stay; a model that cannot be built stops the run before any
worker (exit 1)."""

from __future__ import annotations

import gzip
import json
import logging
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import ClassVar

import pytest

from conftest import plug_in
from drivenav.agent.base import Agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import OVON
from drivenav.envs.habitat.layouts import read_split, scene_name
from drivenav.episode import Episode
from drivenav.errors import RunStoppedError
from drivenav.eval import runner
from drivenav.eval.episodes import save_episodes
from drivenav.eval.records import read_records
from drivenav.eval.rundir import EPISODES_FILE, REDONE_FILE, read_run
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings
from drivenav.types import Action, Observation, SimConfig

SCENES = "procedural:2"


def _episodes(count: int, scenes: str = SCENES) -> list[Episode]:
    return generate_episodes(SceneLibrary(scenes, 0), count, 0)


def _export(episodes: Path, out: Path, *extra: str) -> int:
    return main(["episodes", "export", "--episodes", str(episodes), "--format", OVON, "--out", str(out), *extra])


def _content_ids(split: Path) -> dict[str, list[str]]:
    found = {}
    for path in sorted((split / "content").glob("*.json.gz")):
        with gzip.open(path, "rt", encoding="utf-8") as handle:
            found[path.name] = [item["episode_id"] for item in json.load(handle)["episodes"]]
    return found


# ------------------------------------------------------------------------------------------------ exports


def test_a_second_export_into_the_same_folder_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second = tmp_path / "a.json.gz", tmp_path / "b.json.gz"
    save_episodes(_episodes(3, "procedural:1"), first)
    save_episodes(_episodes(3, "homes:1"), second)
    assert _export(first, tmp_path / "out") == 0
    before = _content_ids(tmp_path / "out" / "val")
    capsys.readouterr()
    assert _export(second, tmp_path / "out") == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(tmp_path / "out" / "val") in err and "--overwrite" in err, err
    assert _content_ids(tmp_path / "out" / "val") == before  # untouched


def test_overwrite_replaces_an_earlier_export_whole(tmp_path: Path) -> None:
    first, second = tmp_path / "a.json.gz", tmp_path / "b.json.gz"
    save_episodes(_episodes(3, "procedural:1"), first)
    save_episodes(_episodes(3, "homes:1"), second)
    assert _export(first, tmp_path / "out") == 0
    assert _export(second, tmp_path / "out", "--overwrite") == 0
    read = read_split(tmp_path / "out" / "val" / "val.json.gz", OVON)
    assert [e.episode_id for e in read] == [e.episode_id for e in _episodes(3, "homes:1")]
    assert {e.scene_id for e in read} == {e.scene_id for e in _episodes(3, "homes:1")}  # none of the first's
    assert sorted(p.name for p in tmp_path.joinpath("out").iterdir()) == ["val"]  # no staging folder left


def test_overwrite_never_deletes_what_is_no_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    episodes = tmp_path / "a.json.gz"
    save_episodes(_episodes(2, "procedural:1"), episodes)
    (tmp_path / "out" / "val").mkdir(parents=True)
    (tmp_path / "out" / "val" / "notes.txt").write_text("mine", encoding="utf-8")
    assert _export(episodes, tmp_path / "out", "--overwrite") == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "notes.txt" in err, err
    assert (tmp_path / "out" / "val" / "notes.txt").read_text(encoding="utf-8") == "mine"


def test_ids_qualified_and_plain_of_one_scene_stay_apart_and_read_back(tmp_path: Path) -> None:
    one, other = _episodes(2, "procedural:1")
    name = scene_name(one.scene_id)
    episodes = [replace(one, episode_id=f"{name}:7"), replace(other, episode_id="7", scene_id=one.scene_id)]
    source = tmp_path / "eps.json.gz"
    save_episodes(episodes, source)
    assert _export(source, tmp_path / "out") == 0
    (ids,) = _content_ids(tmp_path / "out" / "val").values()
    assert sorted(ids) == sorted([f"{name}:7", "7"])  # not '7' twice
    read = read_split(tmp_path / "out" / "val" / "val.json.gz", OVON)
    assert [e.episode_id for e in read] == [f"{name}:7", "7"]


def test_ids_a_split_qualified_are_still_written_as_the_files_held_them(tmp_path: Path) -> None:
    episodes = _episodes(4)
    scenes = sorted({e.scene_id for e in episodes})
    assert len(scenes) == 2
    qualified = [replace(e, episode_id=f"{scene_name(e.scene_id)}:{i // 2}") for i, e in enumerate(episodes)]
    qualified = [replace(e, scene_id=scenes[i % 2]) for i, e in enumerate(qualified)]
    qualified = [replace(e, episode_id=f"{scene_name(e.scene_id)}:{i // 2}") for i, e in enumerate(qualified)]
    source = tmp_path / "eps.json.gz"
    save_episodes(qualified, source)
    assert _export(source, tmp_path / "out") == 0
    assert all(ids == ["0", "1"] for ids in _content_ids(tmp_path / "out" / "val").values())
    read = read_split(tmp_path / "out" / "val" / "val.json.gz", OVON)
    assert sorted(e.episode_id for e in read) == sorted(e.episode_id for e in qualified)


# ------------------------------------------------------------------------------------------------ reruns


def _spec() -> RunSpec:
    return RunSpec(EmbeddedSpec(SCENES, 0), load_settings("random", options={"sim.max_steps": 20}))


class _Failing(Agent):
    """Raises at the first step of the episodes whose index (in this process, from 0) is in ``failing``, while
    ``broken`` holds; stops at once otherwise."""

    name = "failing"
    broken: ClassVar[bool] = True
    failing: ClassVar[range] = range(0, 4)
    started: ClassVar[int] = 0

    def __init__(self, sim: SimConfig) -> None:
        super().__init__(sim)

    def decide(self, observation: Observation) -> Action:
        if observation.step == 0:
            type(self).started += 1
        if self.broken and self.started - 1 in self.failing:
            raise ZeroDivisionError("cannot start")
        return Action.STOP


@pytest.fixture
def failing(monkeypatch: pytest.MonkeyPatch) -> None:
    real: Callable[[RunSpec], Agent] = runner.build_agent
    monkeypatch.setattr(runner, "_WORKER", None)
    monkeypatch.setattr(runner, "build_agent", lambda s: _Failing(s.settings.sim) if s.agent == "random" else real(s))
    monkeypatch.setattr(_Failing, "broken", True)
    monkeypatch.setattr(_Failing, "failing", range(0, 4))
    monkeypatch.setattr(_Failing, "started", 0)


def test_after_the_fix_a_rerun_runs_again_what_failed_to_start(
    tmp_path: Path, failing: None, caplog: pytest.LogCaptureFixture
) -> None:
    episodes = _episodes(7)
    with pytest.raises(RunStoppedError, match="first 4 episodes all ended in ZeroDivisionError"):
        evaluate(episodes, _spec(), tmp_path, show_progress=False)
    _Failing.broken = False  # the fix
    with caplog.at_level(logging.WARNING):
        summary = evaluate(episodes, _spec(), tmp_path, show_progress=False)
    assert summary.errors == 0 and summary.episodes == 7
    said = [r.getMessage() for r in caplog.records if "run again" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("4 episodes that ended in an error"), said
    records = read_run(tmp_path).records  # every reader: one record per episode, the new one
    assert sorted(r.episode_id for r in records) == sorted(e.episode_id for e in episodes)
    assert not any(r.is_error for r in records)
    kept = read_records(tmp_path / REDONE_FILE)  # nothing lost: the old records moved aside
    assert len(kept) == 4 and all(r.is_error for r in kept)


def test_errors_after_a_finished_episode_stay_as_they_are(tmp_path: Path, failing: None) -> None:
    _Failing.failing = range(1, 100)
    episodes = _episodes(5)
    assert evaluate(episodes, _spec(), tmp_path, show_progress=False).errors == 4
    before = (tmp_path / EPISODES_FILE).read_bytes()
    _Failing.broken = False
    assert evaluate(episodes, _spec(), tmp_path, show_progress=False).errors == 4
    assert (tmp_path / EPISODES_FILE).read_bytes() == before and not (tmp_path / REDONE_FILE).exists()


def test_the_rerun_never_appends_through_a_link(tmp_path: Path, failing: None) -> None:
    episodes = _episodes(5)
    with pytest.raises(RunStoppedError):
        evaluate(episodes, _spec(), tmp_path / "run", show_progress=False)
    (tmp_path / "run" / REDONE_FILE).symlink_to(tmp_path / "run" / EPISODES_FILE)
    _Failing.broken = False
    assert evaluate(episodes, _spec(), tmp_path / "run", show_progress=False).errors == 0
    assert not (tmp_path / "run" / REDONE_FILE).is_symlink()
    assert len(read_records(tmp_path / "run" / EPISODES_FILE)) == 5


# ------------------------------------------------------------------------------------------------ models

BROKEN_MODULE = """
from drivenav.semantics.registry import Backend


def _build(spec):
    raise RuntimeError("no weights for this reasoner")


BROKEN = Backend(_build)
"""


def test_a_model_whose_build_raises_stops_the_run_before_any_episode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "brokenpkg.py").write_text(BROKEN_MODULE, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    plug_in(monkeypatch, ("drivenav.reasoners", "broken-build", "brokenpkg:BROKEN", "broken-build"))
    monkeypatch.setattr(runner, "_WORKER", None)
    args = ["eval", "--agent", "drive-nav", "--scenes", "procedural:1", "--episodes", "2", "--max-steps", "20"]
    assert main([*args, "--reasoner", "broken-build", "--out", str(tmp_path / "run")]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "cannot start" in err and "no weights for this reasoner" in err, err
    assert not (tmp_path / "run" / EPISODES_FILE).exists() or not read_records(tmp_path / "run" / EPISODES_FILE)
