"""A broken or careless plug-in breaks only itself (issue 59, "Isolation"): options that clash with a command's, a
model whose ``check`` or ``connect`` raises, a world whose ``build`` or ``episodes`` raises, ``SystemExit`` or
``KeyboardInterrupt`` at import or inside an episode. Each is one line naming the plug-in and its package (or one
episode's ``error`` record), while ``--help``, ``config show`` and a built-in method's ``eval`` keep working; a real
Ctrl-C still stops a run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO, plug_in
from drivenav import plugins
from drivenav.cli import build_parser, main
from drivenav.errors import InputError
from drivenav.eval import runner
from drivenav.robot.registry import robot_parts
from drivenav.types import SimConfig

PACKAGE = "isolation-hostile"
"""The distribution of the throwaway plug-ins."""

MODULE = """
import os, signal, sys, time
from dataclasses import replace

from drivenav.agent.config import ExplorerEntry
from drivenav.agent.explorers.greedy.config import GreedyConfig
from drivenav.agent.explorers.greedy.explorer import GreedyExplorer
from drivenav.robot.registry import SourceEntry
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.registry import GEOMETRIC_REASONER, Backend
from drivenav.worlds.embedded import EMBEDDED


def fail(error):
    def raising(*args):
        raise error
    return raising


def world(name, **changes):
    return replace(EMBEDDED, name=name, summary=name, **changes)


def options(*flags, **kwargs):
    return lambda group: [group.add_argument(flag, **kwargs) for flag in flags]


CLASH_SCENES = world("clash-scenes", add_options=options("--scenes"))
CLASH_HELP = world("clash-help", add_options=options("-h"))
CLASH_DEST = world("clash-dest", add_options=options("--my-out", dest="out"))
REQUIRED = world("required", add_options=options("--must", required=True))
RAISING_OPTIONS = world("raising-options", add_options=fail(RuntimeError("options broke")))
EXITING_OPTIONS = world("exiting-options", add_options=fail(SystemExit(3)))
FINE = world("fine", add_options=options("--fine-opt"))
BAD_BUILD = world("bad-build", build=fail(RuntimeError("no such world")))
EXIT_BUILD = world("exit-build", build=fail(SystemExit(4)))
BAD_EPISODES = world("bad-episodes", episodes=fail(ValueError("no episodes here")))

NO_SERVER = Backend(GEOMETRIC_REASONER.build, connect=fail(OSError("connection refused")))
BAD_CHECK = Backend(GEOMETRIC_REASONER.build, check=fail(ValueError("bad check")))
INTERRUPT_CONNECT = Backend(GEOMETRIC_REASONER.build, connect=fail(KeyboardInterrupt()))


class ExitGrounder(GroundTruthGrounder):
    def segment(self, observation, phrase):
        raise SystemExit(7)


class InterruptGrounder(GroundTruthGrounder):
    def segment(self, observation, phrase):
        raise KeyboardInterrupt


class SignalGrounder(GroundTruthGrounder):
    def segment(self, observation, phrase):
        os.kill(os.getpid(), signal.SIGINT)  # a real Ctrl-C
        time.sleep(5)
        return []


def grounder(kind):
    return Backend(lambda spec: kind(), reads_labels=True, observes=("semantic",))


EXIT_SEGMENT = grounder(ExitGrounder)
INTERRUPT_SEGMENT = grounder(InterruptGrounder)
SIGNAL_SEGMENT = grounder(SignalGrounder)


class ExitingExplorer(GreedyExplorer):
    def __init__(self, setup):
        raise SystemExit(9)


EXITING = ExplorerEntry("exiting", GreedyConfig, "isopkg:ExitingExplorer", "exits", ("agent.enrich=false",))

BIND_SOURCE = SourceEntry("bind-source", "adds --bind", fail(RuntimeError("unused")), options("--bind"))
EXIT_SOURCE = SourceEntry("exit-source", "exits when built", fail(SystemExit(6)))
"""

WORLDS = (
    "clash-scenes", "clash-help", "clash-dest", "required", "raising-options", "exiting-options", "fine",
    "bad-build", "exit-build", "bad-episodes",
)  # fmt: skip
POINTS = [
    *(("drivenav.worlds", name, f"isopkg:{name.upper().replace('-', '_')}", PACKAGE) for name in WORLDS),
    ("drivenav.reasoners", "no-server", "isopkg:NO_SERVER", PACKAGE),
    ("drivenav.reasoners", "bad-check", "isopkg:BAD_CHECK", PACKAGE),
    ("drivenav.reasoners", "interrupt-connect", "isopkg:INTERRUPT_CONNECT", PACKAGE),
    ("drivenav.grounders", "exit-segment", "isopkg:EXIT_SEGMENT", PACKAGE),
    ("drivenav.grounders", "interrupt-segment", "isopkg:INTERRUPT_SEGMENT", PACKAGE),
    ("drivenav.grounders", "signal-segment", "isopkg:SIGNAL_SEGMENT", PACKAGE),
    ("drivenav.explorers", "exiting", "isopkg:EXITING", PACKAGE),
    ("drivenav.robot_sources", "bind-source", "isopkg:BIND_SOURCE", PACKAGE),
    ("drivenav.robot_sources", "exit-source", "isopkg:EXIT_SOURCE", PACKAGE),
]

EVAL = ["eval", "--agent", "drive-nav", "--scenes", "procedural:1", "--max-steps", "30"]


@pytest.fixture
def hostile(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The throwaway plug-ins installed for one test (module ``isopkg`` of distribution ``isolation-hostile``)."""
    (tmp_path / "isopkg.py").write_text(MODULE, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    plug_in(monkeypatch, *POINTS)
    monkeypatch.setattr(runner, "_WORKER", None)
    monkeypatch.setattr(plugins, "_STOPPED_BY_SIGNAL", False)


def _one_line(err: str, name: str) -> str:
    line = err.strip()
    assert "\n" not in line and line.startswith("drivenav: error: "), err
    assert f"plug-in {name}" in line and PACKAGE in line, line
    return line


def _records(run: Path) -> list[dict[str, object]]:
    lines = (run / "episodes.jsonl").read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines]


@pytest.mark.usefixtures("hostile")
def test_clashing_options_refuse_their_plugin_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build_parser()  # every command's parser builds
    with pytest.raises(SystemExit) as done:
        main(["eval", "--help"])
    assert done.value.code == 0
    shown = capsys.readouterr().out
    assert "--fine-opt" in shown and "--must" not in shown and "--my-out" not in shown
    refused = {
        "clash-scenes": "conflicting option string: --scenes",
        "clash-help": "conflicting option string: -h",
        "clash-dest": "its destination 'out' is the command's",
        "required": "option --must: a positional or required option",
        "raising-options": "add_options: RuntimeError: options broke",
        "exiting-options": "add_options: SystemExit: 3",
    }
    for name, why in refused.items():
        assert main([*EVAL, "--episodes", "1", "--out", str(tmp_path / name), "--env", name]) == 2
        line = _one_line(capsys.readouterr().err, name)
        assert "field '--env'" in line and "whose options fit the command line" in line and why in line, line
        assert not (tmp_path / name).exists()
    assert main(["robot", "serve", "--bind", "tcp://127.0.0.1:*", "--source", "bind-source"]) == 2
    line = _one_line(capsys.readouterr().err, "bind-source")
    assert "conflicting option string: --bind" in line
    with pytest.raises(SystemExit) as done:
        main(["robot", "serve", "--help"])
    assert done.value.code == 0
    args = build_parser().parse_args(["robot", "serve", "--source", "exit-source", "--motion", "none"])
    with pytest.raises(InputError, match=r"plug-in exit-source.*whose build works.*isolation-hostile.*SystemExit: 6"):
        robot_parts(args, SimConfig())


@pytest.mark.usefixtures("hostile")
def test_built_in_commands_work_beside_hostile_plugins(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "show", "--agent", "drive-nav"]) == 0
    assert "explorer:" in capsys.readouterr().out
    assert main(["doctor"]) == 0
    assert main(["doctor", "--env", "exit-build"]) == 0  # its options fit; doctor builds no world
    assert main(["doctor", "--env", "clash-scenes"]) == 0  # doctor has no world options to clash with
    assert main([*EVAL, "--episodes", "1", "--out", str(tmp_path / "run")]) == 0
    assert [r["stop_reason"] for r in _records(tmp_path / "run")] != ["error"]


@pytest.mark.parametrize(
    ("option", "name", "why"),
    [
        ("--env", "bad-build", "whose build works (entry point drivenav.worlds: bad-build = 'isopkg:BAD_BUILD' of"),
        ("--env", "exit-build", "whose build works"),
        ("--env", "bad-episodes", "whose episodes works"),
        ("--reasoner", "no-server", "whose connect works"),
        ("--reasoner", "bad-check", "whose check works"),
        ("--reasoner", "interrupt-connect", "whose connect works"),
    ],
)
@pytest.mark.usefixtures("hostile")
def test_a_failing_world_or_model_is_one_line(
    option: str, name: str, why: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*EVAL, "--episodes", "1", "--out", str(tmp_path / "run"), option, name]) == 2
    line = _one_line(capsys.readouterr().err, name)
    assert f"field '{option}'" in line and why in line, line
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


@pytest.mark.parametrize(
    ("option", "name", "error"),
    [
        ("--detector", "exit-segment", "SystemExit: 7 (raised by plug-in exit-segment, entry point drivenav.grounders"),
        ("--detector", "interrupt-segment", "KeyboardInterrupt: (raised by plug-in interrupt-segment"),
        ("--agent", "exiting", "SystemExit: 9 (raised by plug-in exiting, entry point drivenav.explorers"),
    ],
)
@pytest.mark.usefixtures("hostile")
def test_an_exit_or_interrupt_inside_an_episode_ends_that_episode(
    option: str, name: str, error: str, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    assert main([*EVAL, "--episodes", "2", "--out", str(run), option, name]) == 0
    records = _records(run)
    assert len(records) == 2 and {r["stop_reason"] for r in records} == {"error"}
    assert all(str(r["error"]).startswith(error) and PACKAGE in str(r["error"]) for r in records), records


@pytest.mark.usefixtures("hostile")
def test_the_fail_fast_rule_applies_to_a_plugins_exit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*EVAL, "--episodes", "4", "--out", str(tmp_path / "run"), "--detector", "exit-segment"]) == 1
    assert "the first 4 episodes all ended in SystemExit: 7 (raised by plug-in exit-segment" in capsys.readouterr().err


@pytest.mark.usefixtures("hostile")
def test_a_real_ctrl_c_still_stops_the_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    assert main([*EVAL, "--episodes", "2", "--out", str(run), "--detector", "signal-segment"]) == 130
    assert "interrupted (finished episodes are saved; rerun to resume)" in capsys.readouterr().err
    assert not (run / "episodes.jsonl").is_file() or _records(run) == []  # the interrupted episode is not saved


# -- an installed package whose import exits or is interrupted (the process's exit matters) -----------------------

ENTRY_POINTS = """\
[drivenav.worlds]
exit-import = exitpkg:WORLD

[drivenav.reasoners]
interrupt-import = intpkg:REASONER

[drivenav.explorers]
exit-explorer = exitpkg:EXPLORER
"""


def _drivenav(packages: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(packages)])}
    command = [sys.executable, "-m", "drivenav.cli", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=REPO, env=env, check=False)


def test_an_exit_or_interrupt_at_import_is_one_line_and_breaks_nothing_else(tmp_path: Path) -> None:
    packages = tmp_path / "pkg"
    for module, body in (("exitpkg", "import sys\nsys.exit(5)\n"), ("intpkg", "raise KeyboardInterrupt\n")):
        (packages / module).mkdir(parents=True)
        (packages / module / "__init__.py").write_text(body, encoding="utf-8")
    dist = packages / f"{PACKAGE.replace('-', '_')}-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {PACKAGE}\nVersion: 0.1\n", encoding="utf-8")
    (dist / "entry_points.txt").write_text(ENTRY_POINTS, encoding="utf-8")
    for args in (["--help"], ["eval", "--help"], ["config", "show", "--agent", "drive-nav"], ["doctor"]):
        done = _drivenav(packages, *args)
        assert done.returncode == 0, (args, done.stderr)
    run = tmp_path / "run"
    for option, name, why in (("--env", "exit-import", "SystemExit: 5"), ("--reasoner", "interrupt-import", "Key")):
        done = _drivenav(packages, *EVAL, "--episodes", "1", "--out", str(run), option, name)
        assert done.returncode == 2, done.stderr
        assert why in _one_line(done.stderr, name) and "that can be loaded" in done.stderr
    done = _drivenav(packages, "doctor", "--env", "exit-import")
    assert done.returncode == 2 and "SystemExit: 5" in _one_line(done.stderr, "exit-import")
    done = _drivenav(packages, *EVAL, "--episodes", "1", "--out", str(run))
    assert done.returncode == 0, done.stderr
    assert len(_records(run)) == 1
