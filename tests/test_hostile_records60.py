"""Hostile records and misleading lines (issue 60): a run's records name its own agent, and the lines a user reads
after a refusal name the file, field or option and what was expected.

A record naming another agent than its run's (``vlfm`` inside a ``random`` run) or an agent no registry knows is
refused by every reader (``report``, ``compare``, ``viz``) and by a resume, in one line naming the file, the line
and ``record.agent``, exit 2; runs of presets, plug-ins (installed or not) and records without a ``run.json`` still
read. The OVON reader's duplicate ids, a shared grounder server gone and ``serve grounder --detector embedded``'s
options answer in lines that say what is wrong and what to do.
"""

from __future__ import annotations

import gzip
import json
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.benchmarks import OVON
from drivenav.envs.habitat.layouts import read_split
from drivenav.errors import InputError, RunStoppedError
from drivenav.eval import shared_detector
from drivenav.eval.rundir import EPISODES_FILE, RUN_FILE, read_run
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.semantics import grounder_server
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import Detection
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.served import GrounderUnavailableError, ServedInfo
from drivenav.settings import load_settings
from drivenav.types import Observation
from ovon_fixture import write_released

SCENES = "procedural:2"
EVAL = ["eval", "--agent", "random", "--env", "embedded", "--scenes", SCENES, "--episodes", "2", "--max-steps", "20"]


def _run(out: Path, agent: str = "random") -> Path:
    """A finished two-episode run of ``agent`` in ``out``."""
    spec = RunSpec(EmbeddedSpec(SCENES, 0), load_settings(agent, options={"sim.max_steps": 20}))
    evaluate(generate_episodes(SceneLibrary(SCENES, 0), 2, 0), spec, out, show_progress=False)
    return out


def _rename_agent(out: Path, line: int, agent: str) -> None:
    """Line ``line`` of the run's records, its ``agent`` replaced by ``agent``."""
    path = out / EPISODES_FILE
    lines = path.read_text(encoding="utf-8").splitlines()
    record = json.loads(lines[line - 1])
    lines[line - 1] = json.dumps({**record, "agent": agent}, sort_keys=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _one_line(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    for word in words:
        assert word in err, err
    return err


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory.mktemp("run") / "run")


@pytest.fixture
def run_copy(finished: Path, tmp_path: Path) -> Path:
    """A fresh copy of the finished run (no lock)."""
    out = tmp_path / "run"
    out.mkdir()
    for path in finished.rglob("*"):
        if path.is_file() and path.name != ".lock":
            (out / path.relative_to(finished)).parent.mkdir(parents=True, exist_ok=True)
            (out / path.relative_to(finished)).write_bytes(path.read_bytes())
    return out


@pytest.mark.parametrize("agent", ["vlfm", "no-such-agent"])
def test_a_record_of_another_agent_is_refused_by_every_reader(
    run_copy: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], agent: str
) -> None:
    _rename_agent(run_copy, 2, agent)
    episode = json.loads((run_copy / EPISODES_FILE).read_text().splitlines()[0])["episode_id"]
    where = f"{run_copy / EPISODES_FILE}:2"
    for command in (
        ["report", str(run_copy), "--out", str(tmp_path / "site"), "--pictures", "none"],
        ["compare", str(run_copy)],
        ["viz", str(run_copy), episode, "--out", str(tmp_path / "viz")],
    ):
        assert main(command) == 2, command
        _one_line(capsys, where, "record.agent", "'random', the agent of this run", agent)


def test_a_resume_refuses_a_record_of_another_agent(run_copy: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _rename_agent(run_copy, 1, "vlfm")
    before = (run_copy / EPISODES_FILE).read_bytes()
    assert main([*EVAL, "--out", str(run_copy)]) == 2
    _one_line(capsys, f"{run_copy / EPISODES_FILE}:1", "record.agent", "'random'", "vlfm")
    assert (run_copy / EPISODES_FILE).read_bytes() == before  # nothing taken out or lost


def test_a_run_of_a_preset_and_an_intact_run_read(run_copy: Path, tmp_path: Path) -> None:
    assert {r.agent for r in read_run(run_copy).records} == {"random"}
    preset = _run(tmp_path / "preset", "nearest-frontier")
    assert {r.agent for r in read_run(preset).records} == {"nearest-frontier"}


def test_an_uninstalled_plugins_records_still_read(run_copy: Path) -> None:
    """A run whose run.json names an explorer (and agent) no longer installed: its records name that agent, which
    no registry knows, and still read (its resume is refused by the plug-in's own line)."""
    data = json.loads((run_copy / RUN_FILE).read_text())
    data["config"]["run"]["agent"] = "gone-plugin"
    data["config"]["explorer"] = {"name": "gone-plugin"}
    data["explorer_plugin"] = {"name": "gone-plugin", "value": "gone_pkg:EXPLORER", "distribution": "gone-pkg 0.1"}
    (run_copy / RUN_FILE).write_text(json.dumps(data))
    for line in (1, 2):
        _rename_agent(run_copy, line, "gone-plugin")
    assert {r.agent for r in read_run(run_copy).records} == {"gone-plugin"}
    _rename_agent(run_copy, 2, "random")
    with pytest.raises(InputError, match=r":2: field 'record\.agent': expected 'gone-plugin'"):
        read_run(run_copy)


def test_records_without_run_json_read_as_they_are(run_copy: Path) -> None:
    """Records without a ``run.json`` (a run dir made by hand, a run of a drivenav before run.json) name no run's
    agent to check them against: they read (their resume is refused for the missing run.json)."""
    (run_copy / RUN_FILE).unlink()
    _rename_agent(run_copy, 2, "hand-made")
    assert [r.agent for r in read_run(run_copy).records] == ["random", "hand-made"]


def test_each_run_of_ablations_checks_its_own_run_json(run_copy: Path, tmp_path: Path) -> None:
    """Two runs side by side (as ``bench ablations`` writes them): each record is checked against its own run."""
    other = _run(tmp_path / "greedy", "nearest-frontier")
    assert main(["compare", str(run_copy), str(other)]) == 0
    _rename_agent(other, 1, "random")  # the first run's agent, not this one's
    with pytest.raises(InputError, match=r"greedy/episodes\.jsonl:1: field 'record\.agent': expected 'nearest-fr"):
        read_run(other)


# ------------------------------------------------------------------------------------------------ misleading lines


def _rewrite_content(split_file: Path, name: str, old: str, new: str) -> Path:
    """The split's content file ``name`` with ``old`` replaced by ``new`` throughout; returns the file."""
    path = split_file.parent / "content" / f"{name}.json.gz"
    text = gzip.decompress(path.read_bytes()).decode().replace(old, new)
    path.write_bytes(gzip.compress(text.encode(), mtime=0))
    return path


def test_two_scenes_of_one_base_name_in_a_released_split_are_named_as_the_export_names_them(tmp_path: Path) -> None:
    """house_00001's episodes moved to a scene named house_00000 in another folder: their ids 0 and 1 repeat the
    other file's, and ``<scene>:<id>`` cannot tell the two scenes apart: the line names the scenes and the file."""
    split = write_released(tmp_path)
    content = _rewrite_content(split, "house_00001", "house_00001.basis.glb", "house_00000.basis.glb")
    with pytest.raises(InputError) as error:
        read_split(split, OVON)
    assert error.value.source == str(content) and error.value.field == "scene_id", error.value
    assert "distinct base names" in error.value.expected, error.value
    scenes = "hm3d/val/00800-house_00000/house_00000.basis.glb and hm3d/val/00801-house_00001/house_00000.basis.glb"
    assert error.value.got == scenes, error.value


def test_one_id_twice_in_a_released_scene_names_its_file(tmp_path: Path) -> None:
    split = write_released(tmp_path)
    content = _rewrite_content(split, "house_00001", '"episode_id": "1"', '"episode_id": "0"')
    with pytest.raises(InputError) as error:
        read_split(split, OVON)
    assert error.value.source == str(content) and error.value.field == "episode_id", error.value
    assert error.value.got == "0 twice in hm3d/val/00801-house_00001/house_00001.basis.glb", error.value


class _GoneClient:
    """A served grounder's client whose server no longer answers."""

    def next_id(self) -> int:
        return 1

    def request(self, message: object) -> object:
        raise GrounderUnavailableError("no reply from the grounder server at tcp://127.0.0.1:1 to PING in 2 s")


def test_a_server_of_the_users_gone_keeps_the_advice_to_restart_it() -> None:
    info = ServedInfo("embedded", "", "cpu", "fp32", ("rgb",), False, 1, 0.0)
    grounder = RemoteGrounder(_GoneClient(), info)  # type: ignore[arg-type]
    with pytest.raises(RunStoppedError) as error:
        grounder.begin_episode(None, 0)
    assert "restart or fix the grounder server" in str(error.value), error.value
    assert "rerun the same command to resume" in str(error.value), error.value


def test_the_runs_own_shared_server_gone_says_to_rerun(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--share-detector``'s server killed during the first episode: the next episode's start finds it gone, and
    the stop line says to rerun the same command (a new server is served), not to restart a server the user never
    started."""
    real_endpoint, real_segment = shared_detector._endpoint, RemoteGrounder.segment
    started: list[subprocess.Popen[str]] = []

    def recorded(process: subprocess.Popen[str], log_path: Path, start_s: float) -> str:
        started.append(process)
        return real_endpoint(process, log_path, start_s)

    def killed_at_once(self: RemoteGrounder, frame: Observation, phrase: str) -> list[Detection]:
        if started[0].poll() is None:
            started[0].kill()
            started[0].wait()
        return real_segment(self, frame, phrase)

    monkeypatch.setattr(shared_detector, "_endpoint", recorded)
    monkeypatch.setattr(RemoteGrounder, "segment", killed_at_once)
    run = ["eval", "--agent", "drive-nav", "--scenes", "procedural:2", "--episodes", "2", "--max-steps", "30"]
    run += ["--share-detector", "--set", "models.detector_timeout_s=2", "--out", str(tmp_path / "shared")]
    assert main(run) == 1
    err = capsys.readouterr().err.strip()
    line = err.splitlines()[-1]  # after the progress bar
    assert "Traceback" not in err and line.startswith("drivenav: error: "), err
    for words in ("rerun the same command to resume", "the run's own grounder server", "grounder-server.log"):
        assert words in line, line
    assert "restart or fix" not in line, line


@pytest.mark.parametrize("detector", ["embedded", "ground-truth"])
@pytest.mark.parametrize(
    "given",
    [
        ["--device", "tpu:99"],
        ["--compile"],
        ["--dtype", "bfloat16"],
        ["--detector-model", "/weights"],
        ["--segmenter", "mobilesam"],
        ["--segmenter-model", "/mobile_sam.pt"],
    ],
)
def test_serve_grounder_refuses_model_options_a_stand_in_cannot_honour(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, detector: str, given: list[str]
) -> None:
    """As ``--tiny`` is: one line naming the option, exit 2, before anything is served (a server that would start
    returns at once here)."""
    served: list[object] = []
    monkeypatch.setattr(grounder_server, "build_server", lambda *args: served.append(args))
    monkeypatch.setattr(grounder_server, "run_server", lambda server, curve: None)
    assert main(["serve", "grounder", "--detector", detector, *given, "--bind", "tcp://127.0.0.1:*"]) == 2
    _one_line(capsys, f"'{given[0]}'", "a model detector (sam3, owlv2, grounding-dino)", detector)
    assert served == []


def test_share_detector_serves_a_stand_in_without_model_options() -> None:
    """``eval --share-detector --compile`` (for the scorer) with the embedded detector: its server is given no model
    option (it would refuse them); a model detector's server is given them all."""
    models = ModelSpec(detector="embedded", compile=True, dtype="bfloat16", detector_device="cpu")
    command = shared_detector.server_command(models)
    assert command[-2:] == ["--detector=embedded", "--bind=tcp://127.0.0.1:*"], command
    sam3 = shared_detector.server_command(replace(models, detector="sam3"))
    assert {"--compile", "--dtype=bfloat16", "--device=cpu", "--detector-model="} <= set(sam3), sam3
