"""``drivenav eval --env habitat`` and ``drivenav doctor --env habitat`` end to end (DriveNavSim-v0 in this
process: one worker), and ``bench ablations --env habitat``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PIL import Image
from worlds import SIM_OVERRIDE, export

from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import BENCHMARKS
from drivenav.envs.habitat.layouts import scene_path
from drivenav.eval.records import read_records


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("habitat") / "data"
    export(generate_episodes(SceneLibrary("procedural", 0), 3, 2), folder, "hm3d-ovon")
    return folder


def _eval(data_dir: Path, out: Path, *extra: str) -> int:
    return main(
        [
            "eval", "--env", "habitat", "--config", "hm3d-ovon", "--split", "val_seen", "--data-dir", str(data_dir),
            "--agent", "oracle", "--out", str(out), "--set", SIM_OVERRIDE, *extra,
        ]
    )  # fmt: skip


def test_eval_on_a_habitat_split_writes_records_and_resumes(data_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _eval(data_dir, out, "--episodes", "2") == 0
    records = read_records(out / "episodes.jsonl")
    assert [r.success for r in records] == [1, 1]
    assert all(r.spl is not None and r.spl > 0.9 for r in records)
    run = json.loads((out / "run.json").read_text())
    assert run["config"]["env"]["name"] == "habitat"
    assert run["config"]["env"]["overrides"] == [SIM_OVERRIDE]
    assert run["config"]["sim"]["success_distance"] == 0.25  # the hm3d-ovon preset
    assert _eval(data_dir, out, "--episodes", "2") == 0  # resumes: nothing left to do
    assert len(read_records(out / "episodes.jsonl")) == 2
    assert _eval(data_dir, tmp_path / "all", "--episodes", "all") == 0
    assert len(read_records(tmp_path / "all" / "episodes.jsonl")) == 3
    first = records[0].episode_id
    assert main(["viz", str(out), first, "--out", str(tmp_path / "viz")]) == 0
    (picture,) = (tmp_path / "viz").iterdir()  # the top-down picture only: Habitat scenes are not re-rendered
    assert picture.name == f"{first}_topdown.png"
    with Image.open(picture) as image:
        assert image.width > 200 and image.height > 200


def test_worker_processes_give_the_records_of_one_process(data_dir: Path, tmp_path: Path) -> None:
    plugin = ("--habitat-plugin", "drivenav_sim")  # registers DriveNavSim-v0 in each spawned worker
    assert _eval(data_dir, tmp_path / "one", "--episodes", "all", *plugin) == 0
    assert _eval(data_dir, tmp_path / "two", "--episodes", "all", "--workers", "2", *plugin) == 0
    one = {r.episode_id: r for r in read_records(tmp_path / "one" / "episodes.jsonl")}
    two = {r.episode_id: r for r in read_records(tmp_path / "two" / "episodes.jsonl")}
    assert one == two and len(one) == 3


def test_a_wrong_habitat_lab_override_is_one_line_before_any_work(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _eval(data_dir, tmp_path / "bad", "--episodes", "1", "--set", "habitat.simulator.no_such_key=1") == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("drivenav: error: --set") and "no_such_key" in error and "\n" not in error
    assert not (tmp_path / "bad" / "episodes.jsonl").exists()


def test_doctor_counts_episodes_and_scenes(data_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["doctor", "--env", "habitat", "--config", "hm3d-ovon", "--data-dir", str(data_dir), "--split", "val_seen"]
    assert main(argv) == 1  # no scene files yet
    assert "3 episodes, 3 scenes, 0 scene files found" in capsys.readouterr().out
    scenes = data_dir / "scene_datasets"
    for episode in generate_episodes(SceneLibrary("procedural", 0), 3, 2):
        target = Path(scene_path(episode.scene_id, str(scenes)))
        target.parent.mkdir(parents=True, exist_ok=True)
        target.touch()
    scene_dataset = data_dir / BENCHMARKS["hm3d-ovon"].scene_dataset
    scene_dataset.parent.mkdir(parents=True, exist_ok=True)
    scene_dataset.touch()
    assert main(argv) == 0
    report = capsys.readouterr().out
    assert "habitat-lab" in report and "0.3.320260507" in report
    assert "3 scene files found" in report and "FAIL" not in report


def test_ablations_on_a_habitat_split(data_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "ablations"
    argv = [
        "bench", "ablations", "--env", "habitat", "--config", "hm3d-ovon", "--split", "val_seen",
        "--data-dir", str(data_dir), "--methods", "oracle,random", "--episodes", "2", "--max-steps", "30",
        "--out", str(out), "--set", SIM_OVERRIDE,
    ]  # fmt: skip
    assert main(argv) == 0
    report = json.loads((out / "ablations.json").read_text())
    assert set(report["methods"]) == {"oracle", "random"}
    assert report["pictures"]["episodes"]  # top-down pictures of the trace, as for embedded runs
