"""Every kind of part through entry points (:mod:`drivenav.plugins`): drivenav's own declared in pyproject.toml as in
the code's tables, other packages' found by entry point (a robot's sensor source with an option of its own here), and
a broken plug-in one line with exit 2 when it is named, never breaking the built-in names. A real package installed
beside drivenav is ``tests/test_plugin_package.py``."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tomllib

from conftest import plug_in, registries
from drivenav import plugins
from drivenav.agent.config import ExplorerEntry
from drivenav.agent.explorers import BUILT_IN_EXPLORERS
from drivenav.cli import build_parser, main
from drivenav.errors import InputError
from drivenav.eval import runner
from drivenav.plugins import Registry
from drivenav.robot.parts import MotionResult
from drivenav.robot.registry import robot_parts
from drivenav.types import Action, Pose, SimConfig

ROOT = Path(__file__).parents[1]


def test_every_group_has_a_registry_whose_built_ins_pyproject_declares() -> None:
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    found = registries()
    assert set(found) == set(plugins.GROUPS) == set(declared)
    for group, registry in found.items():
        assert declared[group] == registry.built_ins, group
        for name in registry.built_ins:
            registry.get(name)  # loads, is of its group's kind and (where a part carries one) has its own name


def _fake_points(*points: tuple[str, str, str]) -> list[SimpleNamespace]:
    return [SimpleNamespace(name=n, value=v, dist=SimpleNamespace(name=d)) for n, v, d in points]


def test_a_broken_plugin_is_one_line_and_never_breaks_the_built_ins(monkeypatch: pytest.MonkeyPatch) -> None:
    points = _fake_points(
        ("broken", "no_such_module_anywhere:EXPLORER", "broken-pkg"),
        ("wrongtype", "math:pi", "odd-pkg"),
        ("vlfm", "their_pkg:EXPLORER", "clash-pkg"),
        ("directions", "drivenav.agent.explorers.drive_nav.config:EXPLORER", "drivenav"),
        ("alias", "drivenav.agent.explorers.greedy.config:EXPLORER", "alias-pkg"),
    )
    monkeypatch.setattr(plugins, "entry_points", lambda group: points)
    registry = Registry[ExplorerEntry](
        "drivenav.explorers",
        BUILT_IN_EXPLORERS,
        lambda p: isinstance(p, ExplorerEntry),
        "explorer entry",
        "x",
        named=lambda entry: entry.name,
    )
    assert registry.names == ("directions", "greedy", "vlfm", "apexnav", "alias", "broken", "wrongtype")  # vlfm: ours
    assert registry.get("vlfm").explorer.startswith("drivenav.")
    with pytest.raises(InputError) as broken:
        registry.get("broken")
    line = str(broken.value)
    assert "\n" not in line and "plug-in broken" in line and "broken-pkg" in line
    assert "no_such_module_anywhere:EXPLORER" in line and "ModuleNotFoundError" in line
    with pytest.raises(InputError, match=r"plug-in wrongtype.*odd-pkg.*float, not explorer entry"):
        registry.get("wrongtype")
    with pytest.raises(InputError, match=r"plug-in alias.*alias-pkg.*an entry named 'greedy'"):
        registry.get("alias")
    assert registry.get("directions").name == "directions"
    assert list(registry.usable()) == ["directions", "greedy", "vlfm", "apexnav"]


# -- broken plug-ins of every kind on the command line ----------------------------------------------------------

MISSING = "no_such_module_anywhere:PART"


@pytest.fixture
def broken_plugins(monkeypatch: pytest.MonkeyPatch) -> None:
    """A package whose parts of every kind cannot be imported, and a world that is not a world entry."""
    kinds = [group.removeprefix("drivenav.") for group in plugins.GROUPS]
    plug_in(
        monkeypatch,
        *((f"drivenav.{kind}", f"broken-{kind}", MISSING, "broken-pkg") for kind in kinds),
        ("drivenav.worlds", "odd-world", "math:pi", "odd-pkg"),
    )
    monkeypatch.setattr(runner, "_WORKER", None)


EVAL = ["eval", "--agent", "random", "--scenes", "procedural:1", "--episodes", "1", "--max-steps", "5"]


@pytest.mark.parametrize(
    ("args", "group", "name"),
    [
        (["--env", "broken-worlds"], "drivenav.worlds", "broken-worlds"),
        (["--agent", "broken-explorers"], "drivenav.explorers", "broken-explorers"),
        (["--reasoner", "broken-reasoners"], "drivenav.reasoners", "broken-reasoners"),
        (["--detector", "broken-grounders"], "drivenav.grounders", "broken-grounders"),
        (["--scorer", "broken-scorers"], "drivenav.scorers", "broken-scorers"),
    ],
)
@pytest.mark.usefixtures("broken_plugins")
def test_a_chosen_broken_plugin_is_one_line_and_exit_2(
    args: list[str], group: str, name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*EVAL, "--out", str(tmp_path / "run"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"plug-in {name}" in err and f"entry point {group}: {name} = " in err
    assert MISSING in err and "broken-pkg" in err and "ModuleNotFoundError" in err
    assert not (tmp_path / "run").exists()  # refused before the run started


@pytest.mark.usefixtures("broken_plugins")
def test_a_plugin_of_the_wrong_kind_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*EVAL, "--out", str(tmp_path / "run"), "--env", "odd-world"]) == 2
    err = capsys.readouterr().err.strip()
    assert "plug-in odd-world" in err and "odd-pkg" in err and "float, not world entry" in err


@pytest.mark.usefixtures("broken_plugins")
def test_broken_plugins_leave_the_built_ins_and_the_help_working(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as done:
        main(["eval", "--help"])
    assert done.value.code == 0
    shown = " ".join(capsys.readouterr().out.split())
    assert "broken-worlds" in shown and "the embedded simulator, Habitat or a robot" in shown
    assert main([*EVAL, "--out", str(tmp_path / "run")]) == 0


@pytest.mark.parametrize(
    ("args", "name"), [(["--source", "broken-robot_sources"], "broken-robot_sources"),
                       (["--motion", "broken-robot_motions"], "broken-robot_motions")],
)  # fmt: skip
@pytest.mark.usefixtures("broken_plugins")
def test_a_broken_robot_part_is_one_line(args: list[str], name: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["robot", "serve", "--bind", "tcp://127.0.0.1:*", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"plug-in {name}" in err and "broken-pkg" in err


# -- a robot part from another package ------------------------------------------------------------------------------


def test_a_robot_part_from_another_package_brings_its_options(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The example package's parts (examples/drivenav-example: ``--source frames --frames DIR``, ``--motion
    printed``)."""
    plug_in(
        monkeypatch,
        ("drivenav.robot_sources", "frames", "drivenav_example.robot:FRAMES", "drivenav-example"),
        ("drivenav.robot_motions", "printed", "drivenav_example.robot:PRINTED", "drivenav-example"),
        ("drivenav.robot_motions", "alias", "drivenav_example.robot:PRINTED", "alias-pkg"),  # not its own name
    )
    for index in range(2):
        pose = np.array([index * 0.25, 0.0, 0.5])
        np.savez(tmp_path / f"{index:04d}.npz", rgb=np.zeros((4, 6, 3), np.uint8), depth=np.ones((4, 6)), pose=pose)
    parse = build_parser().parse_args
    args = parse(["robot", "serve", "--source", "frames", "--frames", str(tmp_path), "--motion", "printed"])
    source, motion = robot_parts(args, SimConfig())
    assert source.read().pose == Pose(0.0, 0.0, 0.5) and source.read().pose == Pose(0.25, 0.0, 0.5)
    with pytest.raises(TimeoutError):
        source.read()
    assert motion.execute(Action.TURN_LEFT) == MotionResult(collided=False)
    assert capsys.readouterr().out == "action TURN_LEFT\n"
    with pytest.raises(InputError, match=r"field '--frames': expected a folder of \.npz frames with --source frames"):
        robot_parts(parse(["robot", "serve", "--source", "frames", "--motion", "none"]), SimConfig())
    with pytest.raises(InputError, match="field '--bag': expected only with --source bag"):
        robot_parts(parse(["robot", "serve", "--source", "frames", "--bag", "x"]), SimConfig())
    with pytest.raises(InputError, match="field '--frames': expected only with --source frames"):
        robot_parts(parse(["robot", "serve", "--source", "bag", "--frames", str(tmp_path)]), SimConfig())
    with pytest.raises(InputError, match=r"plug-in alias.*alias-pkg.*an entry named 'printed'"):
        robot_parts(parse(["robot", "serve", "--source", "ros2", "--motion", "alias"]), SimConfig())
    with pytest.raises(SystemExit):
        main(["robot", "serve", "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert "frames: frames replayed from a folder of .npz files" in shown and "--frames" in shown
    assert "ros2: ROS 2 topics" in shown and "printed: each action printed" in shown
