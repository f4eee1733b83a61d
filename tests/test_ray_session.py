"""``bench ablations --executor ray``: one Ray session serves every method's run, and is closed afterwards."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from drivenav.analysis.ablations import run_methods
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.executor import Executor
from drivenav.eval.records import read_records
from drivenav.eval.rundir import EPISODES_FILE
from drivenav.eval.runner import RunSpec
from drivenav.settings import load_settings


def test_one_ray_session_for_all_methods(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ray = pytest.importorskip("ray")
    if ray.is_initialized():  # another test module's instance, still held by this process
        ray.shutdown()
    starts: list[dict[str, Any]] = []
    real_init = ray.init

    def counting_init(*args: Any, **kwargs: Any) -> Any:
        starts.append(kwargs)
        return real_init(*args, **kwargs)

    monkeypatch.setattr(ray, "init", counting_init)
    episodes = generate_episodes(SceneLibrary("procedural:1", 4), 2, seed=4)
    world = EmbeddedSpec("procedural:1", 4)
    options = {"run.seed": 4, "sim.max_steps": 20}
    specs = [RunSpec(world, load_settings(name, options=options)) for name in ("random", "nearest-frontier")]
    dirs = run_methods(episodes, specs, tmp_path, Executor("ray", workers=2))
    assert len(starts) == 1 and starts[0]["num_cpus"] == 2
    assert not ray.is_initialized()
    assert {name: len(read_records(d / EPISODES_FILE)) for name, d in dirs.items()} == {
        "random": 2,
        "nearest-frontier": 2,
    }
