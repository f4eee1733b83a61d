"""Kernels compiled ahead of time (drivenav.jit): used only when built for this key, checked argument by argument,
the same numbers as numba's JIT, and no numba (nor LLVM) in a process that runs episodes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import drivenav.jit as kernels
from conftest import REPO
from drivenav.directions import bearings

BUILT = kernels.compiled_build() is not None
needs_build = pytest.mark.skipif(
    not BUILT and not os.environ.get("CI"), reason="no ahead-of-time build here (python -m drivenav.jit)"
)

EPISODE = """
import json, sys
from pathlib import Path
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.benchmarks.generate import generate_episodes
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings

episodes = generate_episodes(SceneLibrary("procedural:1", 11), 2, seed=11)
settings = load_settings("drive-nav", options={"run.seed": 11, "sim.max_steps": 60})
out = Path(sys.argv[1])
evaluate(episodes, RunSpec(EmbeddedSpec("procedural:1", 11), settings), out, show_progress=False)
lines = (out / "episodes.jsonl").read_text().splitlines()
records = [{k: v for k, v in json.loads(line).items() if k != "vlm_latency_ms"} for line in lines]
print(json.dumps({"numba": "numba" in sys.modules, "llvmlite": "llvmlite" in sys.modules, "records": records}))
"""


def _episodes(out: Path, mode: str) -> dict[str, object]:
    env = {**os.environ, kernels.MODE_VARIABLE: mode}
    done = subprocess.run(
        [sys.executable, "-c", EPISODE, str(out)], capture_output=True, text=True, cwd=REPO, env=env, check=False
    )
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout.splitlines()[-1])
    return result


@needs_build
def test_the_build_is_used_here() -> None:
    assert BUILT, "CI builds the kernels (make test): python -m drivenav.jit"


@needs_build
def test_episodes_run_without_numba_and_give_the_jit_records(tmp_path: Path) -> None:
    compiled = _episodes(tmp_path / "compiled", "")
    jit = _episodes(tmp_path / "jit", "jit")
    assert compiled["numba"] is False and compiled["llvmlite"] is False
    assert jit["numba"] is True
    assert isinstance(compiled["records"], list) and len(compiled["records"]) == 2
    assert compiled["records"] == jit["records"]


@needs_build
def test_compiled_kernels_refuse_arguments_outside_their_signatures() -> None:
    kernel = bearings._crossing_kernel
    assert isinstance(kernel, kernels.CompiledKernel)
    path = np.array([[0.0, 0.0], [0.3, 0.4], [1.0, 1.0]])
    wrong = (
        (path.astype(np.float32), 0.0, 0.0, 0.8),  # dtype
        (np.repeat(path, 2, axis=1)[:, ::2], 0.0, 0.0, 0.8),  # not C-contiguous: would be misread
        (path[None], 0.0, 0.0, 0.8),  # ndim
        (path, "0", 0.0, 0.8),  # a string for a float
        (path, True, 0.0, 0.8),  # a bool for a float
        (path, 0.0, 0.0),  # arity
    )
    for args in wrong:
        with pytest.raises(TypeError, match="no compiled signature"):
            kernel(*args)
    assert kernel(path, 0, np.float32(0.0), np.int64(1)) == kernel.py_func(path, 0.0, 0.0, 1.0)
    assert kernel(path, 0.0, 0.0, 0.8) == kernel.py_func(path, 0.0, 0.0, 0.8)


@pytest.fixture
def fresh_lookup() -> Iterator[None]:
    kernels.compiled_build.cache_clear()
    yield
    kernels.compiled_build.cache_clear()


def test_a_stale_build_or_the_jit_switch_means_no_build(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fresh_lookup: None
) -> None:
    stale = tmp_path / "index.json"
    stale.write_text(json.dumps({"key": "built from other sources", "kernels": {}}), encoding="utf-8")
    monkeypatch.setattr(kernels, "_INDEX", stale)
    assert kernels.compiled_build() is None
    monkeypatch.undo()
    kernels.compiled_build.cache_clear()
    monkeypatch.setenv(kernels.MODE_VARIABLE, "jit")
    assert kernels.compiled_build() is None


def test_the_build_key_follows_every_kernel_source(monkeypatch: pytest.MonkeyPatch) -> None:
    assert {kernels._source(m).name for m in kernels.kernel_modules()} >= {"fmm.py", "render.py", "edt.py", "paths.py"}
    key = kernels.build_key()
    assert key == kernels.build_key()
    real = kernels._source
    monkeypatch.setattr(kernels, "_source", lambda m: REPO / "README.md" if m.endswith("fmm") else real(m))
    assert kernels.build_key() != key


def test_scalar_checks_take_what_numba_would_and_refuse_the_rest() -> None:
    as_int, as_float, as_bool = (kernels.ArgSpec(kind).checker() for kind in ("int", "float", "bool"))
    assert as_int(np.int32(3)) == 3 and type(as_int(np.int32(3))) is int
    assert as_float(2) == 2.0 and type(as_float(np.float32(0.5))) is float
    assert as_bool(np.bool_(True)) is True
    for check, value in ((as_int, 1.5), (as_int, True), (as_float, False), (as_float, "1"), (as_bool, 1)):
        with pytest.raises(TypeError):
            check(value)
