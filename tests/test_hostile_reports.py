"""Hostile run directories read by ``report``, ``compare`` and ``viz`` (issue 44): the report reads only its runs
(every file a run names stays inside it, links resolved), gives each run its own site folder, replaces what it
wrote before and never overwrites what it did not write; every reader checks every record as a resume does and
refuses what a resume refuses, with the same one line (exit 2)."""

from __future__ import annotations

import json
import math
import os
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.analysis.ablations import build_report
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.base import EpisodeMeasures
from drivenav.envs.embedded.env import EmbeddedEnv, EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval import runner
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.rundir import EPISODES_COPY, EPISODES_FILE, LOCK_FILE, RUN_FILE, episodes_sha256, read_run
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.report.manifest import MANIFEST
from drivenav.report.site import write_report
from drivenav.settings import load_settings
from drivenav.viz.episode import load_episode, render_episode_pictures

SCENES = "procedural:2"
SECRET = "drivenav-test-secret-4f1c"  # what must never reach a site


def _spec(seed: int = 0) -> RunSpec:
    return RunSpec(EmbeddedSpec(SCENES, 0), load_settings("random", options={"sim.max_steps": 15, "run.seed": seed}))


def _episodes(count: int = 3, seed: int = 0) -> list[Episode]:
    return generate_episodes(SceneLibrary(SCENES, 0), count, seed)


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished three-episode run of the random agent (copied by each test before it is damaged)."""
    runner._release_worker()
    out = tmp_path_factory.mktemp("finished") / "run"
    evaluate(_episodes(), _spec(), out, show_progress=False)
    return out


@pytest.fixture(scope="module")
def redone(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same episodes run again with another seed: other trajectories."""
    runner._release_worker()
    out = tmp_path_factory.mktemp("redone") / "run"
    evaluate(_episodes(), _spec(seed=7), out, show_progress=False)
    return out


def _copy(run: Path, target: Path) -> Path:
    shutil.copytree(run, target)
    return target


def _rows(run: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (run / EPISODES_FILE).read_text().splitlines()]


def _write_rows(run: Path, rows: list[dict[str, object]]) -> None:
    (run / EPISODES_FILE).write_text("".join(json.dumps(row) + "\n" for row in rows))


def _one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith("drivenav: error: "), err
    return err.removeprefix("drivenav: error: ")


def _report(capsys: pytest.CaptureFixture[str], *args: str | Path) -> int:
    code = main(["report", *map(str, args), "--workers", "1"])
    if code == 0:
        capsys.readouterr()
    return code


def _lines_of_every_reader(capsys: pytest.CaptureFixture[str], run: Path, tmp_path: Path) -> set[str]:
    """The one line each reader (``report``, ``compare``, ``viz``) refuses ``run`` with (each exits 2)."""
    commands = [
        ["report", str(run), "--out", str(tmp_path / "site"), "--workers", "1"],
        ["compare", str(run)],
        ["viz", str(run), "0", "--out", str(tmp_path / "viz")],
    ]
    lines = set()
    for command in commands:
        assert main(command) == 2, command
        lines.add(_one_line_error(capsys))
    return lines


def _site_bytes(site: Path) -> list[bytes]:
    return [path.read_bytes() for path in site.rglob("*") if path.is_file()]


def _page(site: Path, episode_id: str = "0") -> str:
    (page,) = site.glob(f"runs/*/episodes/{episode_id}.html")
    return page.read_text(encoding="utf-8")


# ------------------------------------------------------------------------- the report reads only its runs


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    secret = tmp_path / "secret.txt"
    secret.write_text(f"API_KEY={SECRET}\n")
    return secret


@pytest.mark.parametrize("named", ["/proc/self/environ", "/etc/passwd", "../../../../etc/hostname", "SECRET"])
def test_a_record_naming_a_file_outside_its_run_is_shown_as_such_never_copied(
    finished: Path,
    tmp_path: Path,
    secret_file: Path,
    named: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("DRIVENAV_TEST_SECRET", SECRET)  # what /proc/self/environ would publish
    run = _copy(finished, tmp_path / "run")
    named = str(secret_file) if named == "SECRET" else named
    rows = _rows(run)
    rows[0]["trace"] = named
    _write_rows(run, rows)
    outside = [Path(p) for p in ("/proc/self/environ", "/etc/passwd", "/etc/hostname") if Path(p).is_file()]
    forbidden = [secret_file.read_bytes(), *(p.read_bytes() for p in outside if os.access(p, os.R_OK))]
    assert _report(capsys, run, "--out", tmp_path / "site") == 0
    site = _site_bytes(tmp_path / "site")
    assert not any(SECRET.encode() in data or data in forbidden for data in site)
    page = _page(tmp_path / "site")
    assert "leads out of the run directory: not read, not copied" in page and "the trace (JSON)" not in page
    assert "the trace (JSON)" in _page(tmp_path / "site", "1")  # the other episodes keep theirs


def test_a_trace_that_is_a_link_out_of_its_run_is_neither_read_nor_copied(
    finished: Path, tmp_path: Path, secret_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    (run / "traces" / "0.json").unlink()
    (run / "traces" / "0.json").symlink_to(secret_file)
    assert _report(capsys, run, "--out", tmp_path / "site") == 0
    assert not any(SECRET.encode() in data for data in _site_bytes(tmp_path / "site"))
    assert "&#x27;traces/0.json&#x27; leads out of the run directory" in _page(tmp_path / "site")


def test_a_link_that_stays_inside_the_run_is_followed(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    (run / "kept").mkdir()
    (run / "traces" / "0.json").rename(run / "kept" / "0.json")
    (run / "traces" / "0.json").symlink_to(Path("..") / "kept" / "0.json")
    assert _report(capsys, run, "--out", tmp_path / "site") == 0
    copied = next((tmp_path / "site" / "runs").glob("*/traces/0.json"))
    assert copied.read_bytes() == (run / "kept" / "0.json").read_bytes() and not copied.is_symlink()
    assert "leads out" not in _page(tmp_path / "site")


@pytest.mark.parametrize("folder", ["viz", "ablations"])
def test_a_picture_that_is_a_link_out_of_its_folder_is_named_never_copied(
    finished: Path, tmp_path: Path, secret_file: Path, folder: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A picture of the run's ``viz/``, or of a ``bench ablations`` directory's ``pictures/<method>/``, that is a link
    out of the run (of that directory) is not copied and its page says so."""
    if folder == "viz":
        run = _copy(finished, tmp_path / "run")
        pictures = run / "viz"
    else:
        run = _copy(finished, tmp_path / "abl" / "runs" / "random")
        pictures = tmp_path / "abl" / "pictures" / "random"
    pictures.mkdir(parents=True)
    (pictures / "0_topdown.png").symlink_to(secret_file)
    assert _report(capsys, run, "--out", tmp_path / "site", "--pictures", "none") == 0
    assert not any(SECRET.encode() in data for data in _site_bytes(tmp_path / "site"))
    assert "0_topdown.png leads out of the " in _page(tmp_path / "site")


@pytest.mark.parametrize("name", [EPISODES_FILE, RUN_FILE, EPISODES_COPY])
def test_a_run_file_that_is_a_link_out_of_the_run_is_refused_by_every_reader(
    finished: Path, redone: Path, tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    (run / name).unlink()
    (run / name).symlink_to(redone / name)
    expected = f"{run / name}: field '{name}': expected a file inside the run directory, got 'a link out of it'"
    assert _lines_of_every_reader(capsys, run, tmp_path) == {expected}


def test_a_resume_never_writes_through_a_link_out_of_the_run(finished: Path, tmp_path: Path, secret_file: Path) -> None:
    run = _copy(finished, tmp_path / "run")
    (run / LOCK_FILE).unlink(missing_ok=True)
    (run / LOCK_FILE).symlink_to(secret_file)  # the lock is truncated and rewritten by the run holding it
    intact = secret_file.read_bytes()
    with pytest.raises(InputError, match=r"\.lock.*a link out of it"):
        evaluate(_episodes(), _spec(), run, show_progress=False)
    assert secret_file.read_bytes() == intact
    (run / LOCK_FILE).unlink()
    (run / "summary.json.tmp").symlink_to(secret_file)  # a temporary file left as a link
    evaluate(_episodes(), _spec(), run, show_progress=False)
    assert secret_file.read_bytes() == intact and json.loads((run / "summary.json").read_text())["episodes"] == 3


# ------------------------------------------------------------------------- one site folder per run, owned files


@pytest.mark.parametrize(("first", "second"), [("r a", "r_a"), ("rün", "r_n"), ("实验一", "实验二")])
def test_runs_whose_names_differ_outside_plain_letters_get_their_own_site_folders(
    finished: Path, redone: Path, tmp_path: Path, first: str, second: str, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = _copy(finished, tmp_path / first), _copy(redone, tmp_path / second)
    assert _report(capsys, a, b, "--out", tmp_path / "site") == 0
    site = tmp_path / "site"
    folders = list((site / "runs").iterdir())
    assert len(folders) == 2 and all(len(list((f / "episodes").glob("*.html"))) == 3 for f in folders)
    traces = {path.read_bytes() for path in site.rglob("traces/0.json")}
    assert traces == {(a / "traces" / "0.json").read_bytes(), (b / "traces" / "0.json").read_bytes()}
    episodes = (site / "episodes.html").read_text(encoding="utf-8")
    assert episodes.count('data-episode="0"') == 2
    pivot = (site / "pivot.html").read_text(encoding="utf-8")
    ids = [part.split('"')[0] for part in pivot.split(' id="pair-')[1:]]
    assert len(ids) == len(set(ids))


def test_a_report_written_again_replaces_the_pictures_of_a_redone_run(
    finished: Path, redone: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    site = tmp_path / "site"
    assert _report(capsys, run, "--out", site, "--pictures", "all") == 0
    old = {path.name: path.read_bytes() for path in site.rglob("pictures/*.png")}
    shutil.rmtree(run)
    _copy(redone, run)  # the run redone in the same folder
    assert _report(capsys, run, "--out", site, "--pictures", "all") == 0
    assert _report(capsys, run, "--out", tmp_path / "fresh", "--pictures", "all") == 0
    new = {path.name: path.read_bytes() for path in site.rglob("pictures/*.png")}
    fresh = {path.name: path.read_bytes() for path in (tmp_path / "fresh").rglob("pictures/*.png")}
    assert new == fresh and set(new) == set(old) and new != old
    assert next(site.rglob("traces/0.json")).read_bytes() == (redone / "traces" / "0.json").read_bytes()


def test_a_report_written_again_holds_only_its_own_runs(
    finished: Path, redone: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = _copy(finished, tmp_path / "a"), _copy(redone, tmp_path / "b")
    site = tmp_path / "site"
    assert _report(capsys, a, b, "--out", site) == 0
    assert _report(capsys, b, "--out", site) == 0
    assert sorted(path.name for path in (site / "runs").iterdir()) == ["b"]
    owned = json.loads((site / MANIFEST).read_text())["files"]
    written = sorted(str(p.relative_to(site)) for p in site.rglob("*") if p.is_file() and p.name != MANIFEST)
    assert set(written) <= set(owned) and "runs/b/episodes/0.html" in owned


@pytest.mark.parametrize("name", ["index.html", "assets/report.css", "runs/run/episodes/0.html"])
def test_a_report_never_overwrites_a_file_it_did_not_write(
    finished: Path, tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    site = tmp_path / "site"
    (site / name).parent.mkdir(parents=True)
    (site / name).write_text("my own file")
    assert _report(capsys, finished, "--out", site) == 2
    err = _one_line_error(capsys)
    assert err.startswith(f"{site / name}: field '--out'") and "a file it did not write" in err
    assert (site / name).read_text() == "my own file"
    assert not (site / MANIFEST).exists()


@pytest.mark.parametrize("entry", ["../victim.txt", "/tmp/victim.txt", "runs/../../victim.txt", 7])
def test_a_manifest_naming_files_outside_the_site_is_refused(
    finished: Path, tmp_path: Path, entry: object, capsys: pytest.CaptureFixture[str]
) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / MANIFEST).write_text(json.dumps({"format": 1, "files": [entry]}))
    victim = tmp_path / "victim.txt"
    victim.write_text("kept")
    assert _report(capsys, finished, "--out", site) == 2
    assert _one_line_error(capsys).startswith(f"{site / MANIFEST}: field 'files'")
    assert victim.read_text() == "kept"


def test_an_owned_file_replaced_by_a_link_is_removed_never_followed(
    finished: Path, tmp_path: Path, secret_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    site = tmp_path / "site"
    assert _report(capsys, finished, "--out", site) == 0
    (site / "index.html").unlink()
    (site / "index.html").symlink_to(secret_file)
    intact = secret_file.read_bytes()
    assert _report(capsys, finished, "--out", site) == 0
    assert secret_file.read_bytes() == intact and not (site / "index.html").is_symlink()


def test_out_holding_the_runs_is_refused_before_anything_is_written(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    abl = tmp_path / "abl"
    runs = [_copy(finished, abl / "runs" / name) for name in ("drive-nav", "frontier")]
    before = sorted(str(p) for p in abl.rglob("*"))
    assert _report(capsys, *runs, "--out", abl) == 2
    assert "expected a folder that holds none of the runs" in _one_line_error(capsys)
    assert sorted(str(p) for p in abl.rglob("*")) == before
    assert _report(capsys, runs[0], "--out", runs[0]) == 2
    _one_line_error(capsys)


def _swap_copy(run: Path) -> None:
    save_episodes(_episodes(seed=1), run / EPISODES_COPY)  # other episodes under the same ids


def test_a_swapped_episodes_copy_is_refused_by_every_reader(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    _swap_copy(run)
    expected = (
        f"{run / EPISODES_COPY}: field 'episodes': expected the episodes whose sha256 run.json records "
        "(episodes_sha256), got 'a copy of other episodes'"
    )
    assert _lines_of_every_reader(capsys, run, tmp_path) == {expected}


# ------------------------------------------------------------------------- every reader checks every record


IMPOSSIBLE = [
    ("success", 7, "0, 1 or null"),
    ("spl", 55.5, "a number in [0, 1] or null"),
    ("steps", -40, "a finite number >= 0"),
    ("spl", math.nan, "a number in [0, 1] or null"),
    ("path_length", math.inf, "a finite number >= 0"),
    ("collisions", -1, "a finite number >= 0"),
    ("vlm_latency_ms", {"direction": -3.0}, "a finite number >= 0"),
]


@pytest.mark.parametrize(("key", "value", "expected"), IMPOSSIBLE, ids=[f"{k}={v}" for k, v, _ in IMPOSSIBLE])
def test_an_impossible_record_is_refused_by_every_reader_with_the_resumes_line(
    finished: Path, tmp_path: Path, key: str, value: object, expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    rows = _rows(run)
    rows[1][key] = value
    _write_rows(run, rows)  # NaN and Infinity as Python's json writes them
    summary = (run / "summary.json").read_bytes()
    with pytest.raises(InputError) as resumed:
        evaluate(_episodes(), _spec(), run, show_progress=False)
    line = str(resumed.value)
    assert line.startswith(f"{run / EPISODES_FILE}:2: field 'record.{key}': expected {expected}, got ")
    assert _lines_of_every_reader(capsys, run, tmp_path) == {line}
    assert (run / "summary.json").read_bytes() == summary  # the resume wrote no summary of it


def test_a_record_of_an_episode_outside_the_run_is_refused_by_every_reader_with_the_resumes_line(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    rows = _rows(run)
    _write_rows(run, [*rows, {**rows[0], "episode_id": "99"}])
    with pytest.raises(InputError) as resumed:
        evaluate(_episodes(), _spec(), run, show_progress=False)
    line = str(resumed.value)
    assert "line 4" in line and "episode '99', which is not in this run" in line
    assert _lines_of_every_reader(capsys, run, tmp_path) == {line}


def test_a_run_without_its_copy_or_run_json_is_still_read(finished: Path, tmp_path: Path) -> None:
    """A run killed before its copy was written (or one from before run.json) is read: what can be checked is."""
    run = _copy(finished, tmp_path / "run")
    (run / EPISODES_COPY).unlink()
    assert len(read_run(run).records) == 3
    (run / RUN_FILE).unlink()
    contents = read_run(run)
    assert contents.info is None and contents.episodes is None and len(contents.records) == 3


class _Overmeasured(EmbeddedEnv):
    """A world (a robot, say) that measures what no episode can have."""

    def measures(self) -> EpisodeMeasures:
        return replace(super().measures(), success=7, spl=55.5)


def test_a_world_measuring_the_impossible_ends_the_episode_in_an_error_never_an_unreadable_record() -> None:
    env = _Overmeasured(SceneLibrary(SCENES, 0).load)
    record, _ = runner.run_episode(env, runner.build_agent(_spec()), _episodes(1)[0], 0, 5)
    assert record.stop_reason == "error" and "the world measured success = 7" in record.error
    assert record.success is None and record.spl is None
    assert EpisodeRecord.from_json(record.to_json()) == record  # every reader reads it


# ------------------------------------------------------------------------- ids, ablations.json, other worlds


@pytest.fixture
def odd_ids(tmp_path: Path) -> Path:
    """An episodes file whose ids Python reads as digits but int() refuses: '²' and 5000 digits."""
    ids = ["²", "1" * 5000, "3"]
    episodes = [replace(e, episode_id=i) for e, i in zip(_episodes(), ids, strict=True)]
    path = tmp_path / "odd.json.gz"
    save_episodes(episodes, path)
    return path


def test_ids_that_are_digits_only_to_python_report_and_end_bench_ablations(
    odd_ids: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runner._release_worker()
    run = tmp_path / "run"
    evaluate(load_episodes(odd_ids), _spec(), run, show_progress=False)
    assert _report(capsys, run, "--out", tmp_path / "site") == 0
    rows = (tmp_path / "site" / "episodes.html").read_text(encoding="utf-8").split('data-episode="')[1:]
    assert [row.split('"')[0] for row in rows] == ["3", "1" * 5000, "²"]  # numbers in number order, then text
    args = ["bench", "ablations", "--episodes", str(odd_ids), "--methods", "random", "--max-steps", "5"]
    assert main([*args, "--scenes", SCENES, "--pictures", "0", "--out", str(tmp_path / "abl")]) == 0
    assert "report: " in capsys.readouterr().out


@pytest.fixture
def ablation_set(finished: Path, tmp_path: Path) -> list[Path]:
    """A ``bench ablations`` folder of two paper methods (the runs are the random agent's: only names matter)."""
    return [_copy(finished, tmp_path / "abl" / "runs" / name) for name in ("drive-nav", "frontier")]


def _ablations_json(runs: list[Path]) -> dict[str, object]:
    records = {run.name: {r.episode_id: r for r in read_run(run).records} for run in runs}
    report = build_report({run.name: run for run in runs}, records, _spec(), 3)
    data: dict[str, object] = report.to_json()
    return data


@pytest.mark.parametrize("damage", ["no JSON", "a list", "methods of another shape", "a value that does not print"])
def test_a_garbage_ablations_json_is_one_line(
    ablation_set: list[Path], tmp_path: Path, damage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "abl" / "ablations.json"
    data = _ablations_json(ablation_set)
    if damage == "a value that does not print":
        slow = {"calls": 1, "calls_per_episode": 1.0, "mean_latency_ms": "slow"}
        data["runtime"]["model_calls"] = {"direction": slow}  # type: ignore[index]
    text = {"no JSON": "garbage{", "a list": "[1, 2]", "methods of another shape": '{"methods": 3}'}
    path.write_text(text.get(damage, json.dumps(data)))
    assert _report(capsys, *ablation_set, "--out", tmp_path / "site") == 2
    err = _one_line_error(capsys)
    assert err.startswith(f"{path}: field '<document>': expected an ablations.json written by 'drivenav bench")


def test_an_ablations_json_of_other_numbers_is_not_shown_beside_the_runs(
    ablation_set: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ablations_json(ablation_set)
    (tmp_path / "abl" / "ablations.json").write_text(json.dumps(data))
    assert _report(capsys, *ablation_set, "--out", tmp_path / "stored") == 0
    data["methods"]["drive-nav"]["success_rate"] = 0.99  # type: ignore[index]
    (tmp_path / "abl" / "ablations.json").write_text(json.dumps(data))
    assert _report(capsys, *ablation_set, "--out", tmp_path / "doctored") == 0
    doctored = (tmp_path / "doctored" / "index.html").read_text(encoding="utf-8")
    assert "99.0" not in doctored
    assert doctored == (tmp_path / "stored" / "index.html").read_text(encoding="utf-8")


def test_an_episodes_copy_naming_another_worlds_scene_is_one_line_in_viz_and_a_note_in_the_report(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(finished, tmp_path / "run")
    scene = "hm3d/00800-TEEsavR23oF/TEEsavR23oF.basis.glb"
    episodes = [replace(e, scene_id=scene) for e in load_episodes(run / EPISODES_COPY)]
    save_episodes(episodes, run / EPISODES_COPY)
    info = json.loads((run / RUN_FILE).read_text())
    (run / RUN_FILE).write_text(json.dumps({**info, "episodes_sha256": episodes_sha256(episodes)}))
    _write_rows(run, [{**row, "scene_id": scene} for row in _rows(run)])
    expected = f"{run / EPISODES_COPY}: field 'scene_id': expected a scene of the run's embedded world, got '{scene}'"
    assert main(["viz", str(run), "0", "--out", str(tmp_path / "viz")]) == 2
    assert _one_line_error(capsys) == expected
    with pytest.raises(InputError, match="a scene of the run's embedded world"):
        render_episode_pictures(load_episode(run, "0"), tmp_path / "viz")
    assert main(["report", str(run), "--out", str(tmp_path / "site"), "--pictures", "all", "--workers", "1"]) == 0
    assert f"Its picture could not be drawn: {expected}".replace("'", "&#x27;") in _page(tmp_path / "site")
    capsys.readouterr()


def test_write_report_refuses_impossible_records_before_writing_anything(finished: Path, tmp_path: Path) -> None:
    run = _copy(finished, tmp_path / "run")
    rows = _rows(run)
    rows[0]["success"] = 7
    _write_rows(run, rows)
    with pytest.raises(InputError, match=r"record\.success"):
        write_report([run], tmp_path / "site")
    assert not (tmp_path / "site").exists()
