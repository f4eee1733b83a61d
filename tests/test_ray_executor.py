"""``--executor ray``: the same episodes as Ray tasks give the same records, resume included (local instances)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from conftest import run_cli
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.errors import InputError
from drivenav.eval.episodes import save_episodes
from drivenav.eval.executor import Executor
from drivenav.eval.ray_executor import import_ray
from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.rundir import EPISODES_FILE
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings

SEED = 11
SCENES = "procedural:2"
SPEC = RunSpec(EmbeddedSpec(SCENES, SEED), load_settings("random", options={"run.seed": SEED, "sim.max_steps": 40}))


def _episodes_file(tmp_path: Path) -> Path:
    path = tmp_path / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("procedural:2", SEED), 4, seed=SEED), path)
    return path


def _sorted_records(run_dir: Path) -> list[EpisodeRecord]:
    return sorted(read_records(run_dir / EPISODES_FILE), key=lambda r: r.episode_id)


def _serial_reference(tmp_path: Path) -> list[EpisodeRecord]:
    from drivenav.eval.episodes import load_episodes

    out = tmp_path / "serial"
    evaluate(load_episodes(_episodes_file(tmp_path)), SPEC, out, show_progress=False)
    return _sorted_records(out)


def _eval_args(episodes: Path, out: Path) -> list[str]:
    return [
        "eval",
        *("--agent", SPEC.agent, "--scenes", SCENES, "--seed", str(SEED), "--max-steps", str(SPEC.max_steps)),
        *("--episodes", str(episodes), "--out", str(out)),
    ]


@pytest.fixture(scope="module")
def ray_cluster() -> Iterator[str]:
    """A local Ray instance started by this test process; its address, for ``--ray-address``."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, object_store_memory=100 * 1024 * 1024)
    try:
        yield str(ray.get_runtime_context().gcs_address)
    finally:
        ray.shutdown()


def test_private_ray_instance_gives_the_serial_records(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    reference = _serial_reference(tmp_path)
    out = tmp_path / "ray"
    args = _eval_args(tmp_path / "episodes.json.gz", out)
    result = run_cli(*args, "--executor", "ray", "--workers", "2")
    assert result.returncode == 0, result.stderr
    assert _sorted_records(out) == reference
    assert len(list((out / "traces").glob("*.json"))) == 4
    assert (out / "summary.json").exists()


def test_resume_on_a_ray_cluster_runs_only_the_rest(tmp_path: Path, ray_cluster: str) -> None:
    from drivenav.eval.episodes import load_episodes

    reference = _serial_reference(tmp_path)
    episodes = load_episodes(tmp_path / "episodes.json.gz")
    out = tmp_path / "resumed"
    evaluate(episodes, SPEC, out, show_progress=False)
    lines = (out / EPISODES_FILE).read_text().splitlines()
    (out / EPISODES_FILE).write_text("\n".join(lines[:2]) + "\n")  # a run that stopped half way, locally
    result = run_cli(*_eval_args(tmp_path / "episodes.json.gz", out), "--executor", "ray", "--ray-address", ray_cluster)
    assert result.returncode == 0, result.stderr
    lines = (out / EPISODES_FILE).read_text().splitlines()
    assert len(lines) == 4  # nothing duplicated
    assert _sorted_records(out) == reference
    evaluate(episodes, SPEC, out, Executor("ray", workers=2), show_progress=False)  # in-process, nothing left
    assert len((out / EPISODES_FILE).read_text().splitlines()) == 4


def test_ray_actors_in_this_process_give_the_serial_records(tmp_path: Path, ray_cluster: str) -> None:
    from drivenav.eval.episodes import load_episodes

    reference = _serial_reference(tmp_path)
    out = tmp_path / "in-process"
    evaluate(load_episodes(tmp_path / "episodes.json.gz"), SPEC, out, Executor("ray", 3), show_progress=False)
    assert _sorted_records(out) == reference


def test_executor_options_are_checked() -> None:
    with pytest.raises(InputError, match="--executor"):
        Executor("dask")
    with pytest.raises(InputError, match="--ray-address"):
        Executor("local", ray_address="127.0.0.1:6379")
    with pytest.raises(InputError, match="--workers"):
        Executor("ray", workers=0)


def test_missing_ray_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # makes `import ray` fail
    with pytest.raises(InputError, match=r"drivenav\[ray\]"):
        import_ray()
