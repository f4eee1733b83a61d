"""A new world is one module and one registry line: the embedded world seen through a noisy depth camera, run end
to end through ``drivenav eval``.

What a new world touches:

1. one module with its spec (a frozen dataclass: ``name``, ``provides``, ``build(sim) -> Env``), its env, and a
   :class:`~drivenav.eval.worlds.entry.WorldEntry` saying how the command line builds the spec, which options it
   adds, where the episodes come from and how a run is titled (this file, from ``NoisyDepthSpec`` to ``NOISY``);
2. one line, ``register(NOISY)`` (:func:`drivenav.eval.worlds.register`; the built-in worlds are listed in
   ``drivenav/eval/worlds/__init__.py``). Here the fixture registers it for each test only.

Nothing else changes: ``--env`` offers it, its options are refused with other worlds, ``run.json`` records it, a
resume and ``drivenav viz`` rebuild its spec from that record.
"""

from __future__ import annotations

import argparse
import json
import zlib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedEnv, EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode
from drivenav.eval import runner
from drivenav.eval.records import read_records
from drivenav.eval.rundir import EPISODES_FILE, RUN_FILE
from drivenav.eval.worlds import WORLDS, recorded_world
from drivenav.eval.worlds.embedded import load_or_generate, scene_library
from drivenav.eval.worlds.entry import WorldEntry
from drivenav.settings import Settings
from drivenav.types import Action, Observation, SimConfig
from drivenav.viz.episode import load_episode, render_episode_pictures

# --- the new world's module ------------------------------------------------------------------------------------


class NoisyDepthEnv(EmbeddedEnv):
    """The embedded world whose depth camera adds Gaussian noise (seeded per episode)."""

    def __init__(self, spec: NoisyDepthSpec, sim: SimConfig) -> None:
        super().__init__(SceneLibrary(spec.scenes, spec.seed).load, sim)
        self._sigma = spec.depth_noise
        self._rng = np.random.default_rng(0)

    def _noisy(self, observation: Observation) -> Observation:
        noise = self._rng.normal(0.0, self._sigma, observation.depth.shape)
        depth = np.clip(observation.depth + noise, self.config.min_depth, self.config.max_depth)
        return replace(observation, depth=depth.astype(np.float32))

    def reset(self, episode: Episode) -> Observation:
        self._rng = np.random.default_rng(zlib.crc32(episode.episode_id.encode()))
        return self._noisy(super().reset(episode))

    def step(self, action: Action) -> Observation:
        return self._noisy(super().step(action))


@dataclass(frozen=True)
class NoisyDepthSpec(EmbeddedSpec):
    depth_noise: float = 0.05  # metres, the standard deviation
    name: ClassVar[str] = "embedded-noisy"

    def build(self, sim: SimConfig) -> NoisyDepthEnv:
        return NoisyDepthEnv(self, sim)


def _add_options(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--depth-noise", type=float, default=None, help="embedded-noisy: depth noise (m)")


def _build(args: argparse.Namespace, settings: Settings) -> NoisyDepthSpec:
    noise = 0.05 if args.depth_noise is None else args.depth_noise
    return NoisyDepthSpec(args.scenes, settings.run.seed, noise)


NOISY = WorldEntry(
    name="embedded-noisy",
    summary="the embedded simulator with a noisy depth camera",
    spec_class=lambda: NoisyDepthSpec,
    build=_build,
    episodes=load_or_generate,
    label=lambda args: f"{args.scenes} (noisy depth)",
    add_options=_add_options,
    own_options=("--depth-noise",),
    scenes=scene_library,
)

# --- the tests -------------------------------------------------------------------------------------------------

SCENES = "procedural:1"


@pytest.fixture(autouse=True)
def noisy_world(monkeypatch: pytest.MonkeyPatch) -> None:
    """``register(NOISY)`` for one test (``monkeypatch`` takes it out again), and no world kept from another."""
    monkeypatch.setitem(WORLDS, NOISY.name, NOISY)
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
