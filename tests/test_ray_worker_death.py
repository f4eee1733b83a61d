"""``--executor ray`` when Ray's workers die: said at once, in one line, never a silent wait."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from drivenav.cli import main
from drivenav.errors import WorkerDiedError
from drivenav.eval import ray_executor

pytest.importorskip("ray")


def test_workers_that_die_as_they_start_are_reported_in_seconds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ray retries a worker that dies as it starts without a word, and ``ray.init`` waits holding the interpreter:
    the run used to wait minutes in silence."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(
        "import os, sys\nif any('default_worker' in arg for arg in sys.argv):\n    os._exit(3)\n"
    )
    monkeypatch.setenv("PYTHONPATH", str(site))
    monkeypatch.setattr(ray_executor, "WORKER_START_S", 8.0)
    started = time.monotonic()
    args = ["eval", "--agent", "random", "--scenes", "procedural:1", "--episodes", "2", "--max-steps", "5"]
    code = main([*args, "--executor", "ray", "--workers", "1", "--out", str(tmp_path / "run")])
    assert code == 1 and time.monotonic() - started < 30
    message = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress bar's lines
    assert message.startswith("drivenav: error: no Ray worker ran a task within 8 s"), message
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


def test_a_worker_that_dies_on_an_episode_names_it() -> None:
    def die(item: str) -> str:  # defined here, so Ray sends it by value to workers that cannot import the tests
        if item == "b":
            os._exit(3)
        return item

    with pytest.raises(WorkerDiedError, match="episode b died"):
        list(ray_executor.run_on_ray(["a", "b", "c"], die, 1, None, key=str))
