"""A new world is a module or two and one entry point: the embedded world seen through a noisy depth camera (the
example plug-in package's, ``examples/drivenav-example``), run end to end through ``drivenav eval``.

What a new world touches (docs/extending.md):

1. its spec (a frozen dataclass: ``name``, ``provides``, ``build(sim) -> Env``) and its env
   (``drivenav_example/noisy_depth.py``), and a light module with its
   :class:`~drivenav.worlds.entry.WorldEntry` saying how the command line builds the spec, which options it
   adds, where the episodes come from and how a run is titled (``drivenav_example/world.py``);
2. one entry point in its package's metadata: ``[project.entry-points."drivenav.worlds"]
   embedded-noisy = "drivenav_example.world:NOISY"`` (drivenav's own worlds are declared the same way in its
   pyproject.toml and listed in ``drivenav/worlds/__init__.py``). Here the fixture declares it for each test
   (the package's sources are on the tests' path, its metadata is not installed); ``tests/test_plugin_package.py``
   installs the package beside drivenav in a fresh venv.

Nothing else changes: ``--env`` offers it, its options are refused with other worlds, ``run.json`` records it, a
resume and ``drivenav viz`` rebuild its spec from that record.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from drivenav_example.noisy_depth import NoisyDepthSpec
from drivenav_example.world import NOISY

from conftest import plug_in
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.eval import runner
from drivenav.eval.records import read_records
from drivenav.eval.rundir import EPISODES_FILE, RUN_FILE
from drivenav.settings import Settings
from drivenav.types import SimConfig
from drivenav.viz.episode import load_episode, render_episode_pictures
from drivenav.worlds import recorded_world
from drivenav.worlds.embedded import load_or_generate

# --- the tests -------------------------------------------------------------------------------------------------

SCENES = "procedural:1"


@pytest.fixture(autouse=True)
def noisy_world(monkeypatch: pytest.MonkeyPatch) -> None:
    """The world declared by an entry point for one test (``monkeypatch`` takes it out again), and no world kept
    from another."""
    plug_in(monkeypatch, ("drivenav.worlds", NOISY.name, "drivenav_example.world:NOISY", "drivenav-example"))
    monkeypatch.setattr(runner, "_WORKER", None)


def _eval(out: Path, *extra: str) -> int:
    args = ["eval", "--env", "embedded-noisy", "--agent", "random", "--scenes", SCENES, "--episodes", "2"]
    return main([*args, "--max-steps", "8", "--out", str(out), *extra])


def test_a_registered_world_runs_end_to_end_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    assert _eval(out, "--depth-noise", "0.1") == 0
    assert "random on procedural:1 (noisy depth)" in capsys.readouterr().out
    record = json.loads((out / RUN_FILE).read_text())["config"]["env"]
    assert record == {"name": "embedded-noisy", "scenes": SCENES, "seed": 0, "depth_noise": 0.1}
    world, spec = recorded_world(record, out / RUN_FILE)
    assert world is NOISY and spec == NoisyDepthSpec(SCENES, 0, 0.1)
    assert _eval(out, "--depth-noise", "0.1") == 0  # the resume: same world, nothing left to run
    assert len(read_records(out / EPISODES_FILE)) == 2


def test_the_world_sees_through_its_own_sensor(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _eval(out) == 0
    episode = load_or_generate(
        argparse.Namespace(scenes=SCENES, episodes="1"), runner.RunSpec(EmbeddedSpec(SCENES, 0), Settings())
    )[0]
    plain = EmbeddedSpec(SCENES, 0).build(SimConfig()).reset(episode)
    noisy = NoisyDepthSpec(SCENES, 0, 0.1).build(SimConfig()).reset(episode)
    assert 0.05 < float(np.abs(noisy.depth - plain.depth).mean()) < 0.15
    first = read_records(out / EPISODES_FILE)[0].episode_id
    pictures = render_episode_pictures(
        load_episode(out, first), tmp_path / "viz", video=False
    )  # its scenes, from run.json
    assert any(p.name.endswith("_start_view.png") for p in pictures)


def test_its_options_are_refused_with_another_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["eval", "--agent", "random", "--episodes", "1", "--out", str(tmp_path / "run"), "--depth-noise", "0.1"]
    assert main(args) == 2
    assert "field '--depth-noise': expected only with --env embedded-noisy" in capsys.readouterr().err


def test_the_command_line_offers_it(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    shown = " ".join(capsys.readouterr().out.split())  # as one line, whatever the terminal's width
    assert "embedded-noisy" in shown and "--depth-noise" in shown
    assert "the embedded simulator, Habitat, a robot or the embedded simulator with a noisy depth camera" in shown
