"""Plug-ins as another package ships them: the example package ``examples/drivenav-example`` (``drivenav-example``: the
``farthest`` explorer, the ``embedded-noisy`` world, the ``frames`` sensor source and the ``printed`` motion executor,
each one entry point in its pyproject.toml) and a broken package beside it (an explorer whose module is missing, a
world that is not a world entry), built and installed next to drivenav's wheel in a fresh venv (offline, from the
wheelhouse ``make test`` fills), then run from an unrelated folder: ``eval`` with the plug-in's method on the
plug-in's world, ``report`` on that run, ``config show`` with the explorer's section, the robot parts and their option
offered by ``robot serve``, and the broken plug-ins refused with one line and exit 2 while ``--agent drive-nav`` still
runs. (``robot serve`` itself needs the ``robot`` extra, which the fresh venv leaves out: ``tests/test_plugins.py``
builds the example's robot parts.)

Then a plug-in's life beside drivenav's own methods, in a venv of its own (it uninstalls the example package): a run
of ``farthest`` and one of ``drive-nav``, whose report shows the explorer's declared counters as columns of the
decisions table and its own trace event on its episode pages; the package uninstalled, both runs still compare and
report, the ``drive-nav`` run resumes, and the ``farthest`` run's rerun is refused in one line naming the entry point
and the package to install."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import REPO
from wheels import clean_env, fresh_venv, run

pytestmark = pytest.mark.slow

BROKEN = {
    "pyproject.toml": """[build-system]
requires = ["setuptools>=68", "wheel"]
build-backend = "setuptools.build_meta"

[project]
name = "drivenav-broken"
version = "0.1.0"
dependencies = ["drivenav"]

[project.entry-points."drivenav.explorers"]
broken = "drivenav_broken.missing:EXPLORER"

[project.entry-points."drivenav.worlds"]
broken-world = "drivenav_broken:NOT_A_WORLD"
""",
    "drivenav_broken/__init__.py": '"""A plug-in package whose parts cannot serve."""\n\nNOT_A_WORLD = "a world"\n',
}
"""A package with a plug-in that cannot be imported and one of the wrong kind."""


def _write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


@pytest.fixture(scope="module")
def drivenav(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with drivenav's wheel, the example plug-in package's and the broken package's; its
    ``drivenav`` command."""
    root = tmp_path_factory.mktemp("plugins")
    python = fresh_venv(root, _example(root), _write(root / "broken", BROKEN))
    return python.parent / "drivenav"


@pytest.fixture(scope="module")
def uninstallable(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv of its own with drivenav's wheel and the example package's (its test uninstalls the example, so
    it shares no venv with other tests); its python."""
    root = tmp_path_factory.mktemp("uninstall")
    return fresh_venv(root, _example(root))


def _example(root: Path) -> Path:
    """The example package's project, copied under ``root`` without anything built in the tree."""
    ignored = shutil.ignore_patterns("__pycache__", "*.egg-info", "build")
    return Path(shutil.copytree(REPO / "examples" / "drivenav-example", root / "example", ignore=ignored))


def _refused(drivenav: Path, *args: str, cwd: Path) -> str:
    """The one line that ``drivenav ARGS`` exits with, status 2."""
    done = subprocess.run([str(drivenav), *args], cwd=cwd, env=clean_env(), capture_output=True, text=True, timeout=600)
    assert done.returncode == 2, f"{args}: exit {done.returncode}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    return done.stderr.strip()


EPISODES = ["--scenes", "procedural:1", "--episodes", "3", "--max-steps", "80"]


def test_a_plugin_method_runs_on_a_plugin_world_beside_a_broken_plugin(drivenav: Path, tmp_path: Path) -> None:
    env = clean_env()
    run(drivenav, "eval", "--agent", "farthest", "--env", "embedded-noisy", "--depth-noise", "0.03", *EPISODES,
        "--out", "run", cwd=tmp_path, env=env)  # fmt: skip
    config = json.loads((tmp_path / "run" / "run.json").read_text())["config"]
    assert config["env"] == {"name": "embedded-noisy", "scenes": "procedural:1", "seed": 0, "depth_noise": 0.03}
    assert config["explorer"]["name"] == "farthest"
    lines = (tmp_path / "run" / "episodes.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    assert len(records) == 3 and not any(record["error"] for record in records)
    assert {record["explorer"]["name"] for record in records} == {"farthest"}
    counters = {"goals_chosen", "longest_goal", "goals_skipped"}
    assert all(set(record["explorer"]["counters"]) == counters for record in records)
    assert all(record["explorer"]["counters"]["goals_chosen"] >= 1 for record in records)
    assert all(record["steps_by_activity"]["start_scan"] == 12 for record in records)

    report = run(drivenav, "report", "run", "--out", "site", cwd=tmp_path, env=env)
    site = tmp_path / "site"
    assert "report:" in report and "embedded-noisy procedural:1" in (site / "index.html").read_text()
    pages = [json.loads((site / "runs" / "run" / "records" / f"{i}.json").read_text()) for i in range(3)]
    assert [page["explorer"] for page in pages] == [record["explorer"] for record in records]
    failed = sum(1 for record in records if not record["success"])  # pictures of failures, in the plug-in's world
    assert len(list((site / "runs" / "run" / "pictures").glob("*_topdown.png"))) == failed

    shown = run(drivenav, "config", "show", "--agent", "farthest", cwd=tmp_path, env=env)
    assert "  farthest:\n    max_travel_time: 12.0" in shown and "name: farthest" in shown

    robot = " ".join(run(drivenav, "robot", "serve", "--help", cwd=tmp_path, env=env).split())
    assert "frames: frames replayed from a folder of .npz files" in robot and "--frames" in robot
    assert "printed: each action printed" in robot and "ros2: ROS 2 topics" in robot

    broken = _refused(drivenav, "eval", "--agent", "broken", *EPISODES, "--out", "broken", cwd=tmp_path)
    assert "plug-in broken" in broken and "drivenav-broken" in broken and "drivenav_broken.missing:EXPLORER" in broken
    wrong = _refused(
        drivenav, "eval", "--agent", "random", "--env", "broken-world", *EPISODES, "--out", "w", cwd=tmp_path
    )
    assert "plug-in broken-world" in wrong and "str, not world entry" in wrong

    run(drivenav, "eval", "--agent", "drive-nav", *EPISODES, "--out", "drive-nav", cwd=tmp_path, env=env)
    assert len((tmp_path / "drive-nav" / "episodes.jsonl").read_text().splitlines()) == 3


def _table(index: str, column: str) -> dict[str, dict[str, str]]:
    """The index page's table that has ``column``: each row's cells by column title, by the row's method."""
    start = index.index(f">{column}</th>")
    table = index[index.rindex("<table>", 0, start) : index.index("</table>", start)]
    titles = re.findall(r"<th[^>]*>(.*?)</th>", table)
    rows = [re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr>(.*?)</tr>", table)]
    return {re.sub(r"</?code>", "", cells[0]): dict(zip(titles, cells, strict=True)) for cells in rows if cells}


def _report(drivenav: Path, cwd: Path, out: str) -> tuple[str, str]:
    """``report`` of both runs into ``out``: the index page and the ``farthest`` run's first episode page."""
    run(drivenav, "report", "farthest", "drive-nav", "--out", out, cwd=cwd, env=clean_env())
    site = cwd / out
    page = site / "runs" / "farthest" / "episodes" / "0.html"
    return (site / "index.html").read_text(encoding="utf-8"), page.read_text(encoding="utf-8")


def test_runs_of_a_plugin_stay_readable_once_it_is_uninstalled(uninstallable: Path, tmp_path: Path) -> None:
    drivenav, env = uninstallable.parent / "drivenav", clean_env()
    farthest = ["eval", "--agent", "farthest", *EPISODES, "--out", "farthest"]
    drive_nav = ["eval", "--agent", "drive-nav", *EPISODES, "--out", "drive-nav"]
    run(drivenav, *farthest, cwd=tmp_path, env=env)
    run(drivenav, *drive_nav, cwd=tmp_path, env=env)
    negative = ["--set", "explorer.farthest.max_travel_time=-5"]
    ranged = _refused(drivenav, "config", "show", "--agent", "farthest", *negative, cwd=tmp_path)
    assert "explorer.farthest.max_travel_time" in ranged and "-5" in ranged  # the section's declared range

    index, page = _report(drivenav, tmp_path, "installed")
    decisions = _table(index, "goals chosen")  # the declared counters' titles
    assert float(decisions["farthest"]["goals chosen"]) >= 1 and decisions["farthest"]["longest goal (m)"] != "-"
    assert decisions["drive-nav"]["goals chosen"] == "-" and decisions["drive-nav"]["decisions"] != "-"
    assert "goals skipped" not in index  # declared out of the table
    assert "Counters of the farthest explorer" in page and "<dt>longest goal (m)</dt>" in page
    assert "Explorer events" in page and "<td>farthest goal</td>" in page and "travel_time: " in page

    run(uninstallable, "-m", "pip", "uninstall", "-q", "-y", "drivenav-example", cwd=tmp_path)
    probe = "import importlib.util as u; print(u.find_spec('drivenav_example') is None)"
    assert run(uninstallable, "-c", probe, cwd=tmp_path, env=env).strip() == "True"
    compared = run(drivenav, "compare", "farthest", "drive-nav", cwd=tmp_path, env=env)
    assert re.search(r"^farthest +3 +0 ", compared, re.M) and re.search(r"^drive-nav +3 +0 ", compared, re.M)
    index, page = _report(drivenav, tmp_path, "uninstalled")
    decisions = _table(index, "goals_chosen")  # undeclared now: titled by their keys
    assert float(decisions["farthest"]["goals_chosen"]) >= 1 and decisions["drive-nav"]["goals_chosen"] == "-"
    assert "Explorer events" in page and "<td>farthest_goal</td>" in page  # kept opaque, named by its kind
    run(drivenav, *drive_nav, cwd=tmp_path, env=env)  # resumed: nothing left to run
    assert len((tmp_path / "drive-nav" / "episodes.jsonl").read_text().splitlines()) == 3
    refused = _refused(drivenav, *farthest, cwd=tmp_path)
    assert (
        "drivenav-example" in refused and "drivenav.explorers: farthest = 'drivenav_example.config:EXPLORER'" in refused
    )
