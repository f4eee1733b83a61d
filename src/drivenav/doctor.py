"""``drivenav doctor``: check a set-up before hours of GPU time (a table of checks, each failure with its fix).

Habitat (``--env habitat``): habitat-sim and habitat-lab import, and for each split of the benchmark (or the one
``--split`` names) the episode file and its ``content/`` files exist, with their episode and scene counts, the
scenes' files under ``DIR/scene_datasets`` and the scene dataset config. Models: the ``openai`` reasoner's server
answers one request with one image in the expected schema (no repair, no fallback); a ``sam3`` / ``owlv2`` /
``grounding-dino`` detector (with its box segmenter) loads and segments one frame; a ``blip2-itm`` / ``siglip``
scorer loads and scores one frame. The process exits 1 if any check failed.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
import platform
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from drivenav import __version__
from drivenav.errors import InputError
from drivenav.jit import compiled_build
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.registry import MODEL_DETECTORS
from drivenav.types import Observation, Pose, SimConfig

if TYPE_CHECKING:
    from drivenav.semantics.protocols import Grounder, ImageTextScorer

Model = TypeVar("Model")

HABITAT_LAB_VERSION = "0.3.320260507"
HABITAT_SIM_FIX = "conda install habitat-sim withbullet headless -c conda-forge -c aihabitat (docs/habitat.md)"
HABITAT_LAB_FIX = f"pip install habitat-lab=={HABITAT_LAB_VERSION} in the environment that has habitat-sim"


@dataclass(frozen=True)
class Check:
    """One line of the doctor's table."""

    name: str
    ok: bool
    detail: str
    fix: str = ""


@dataclass(frozen=True)
class DoctorRequest:
    """What to check: a Habitat benchmark (``benchmark`` empty: none) and the models of ``models``."""

    models: ModelSpec
    benchmark: str = ""
    data_dir: Path | None = None
    split: str | None = None


def kernels_check() -> Check:
    """Which numba kernels this process runs: the ahead-of-time build, or numba's JIT (more memory a process)."""
    if compiled_build() is not None:
        return Check("kernels", True, "compiled ahead of time (no numba JIT in the workers)")
    return Check("kernels", True, "numba's JIT: no build for these sources and versions", "python -m drivenav.jit")


def run_checks(request: DoctorRequest) -> list[Check]:
    """Every check that applies to ``request``, in order."""
    checks = [Check("drivenav", True, f"{__version__} on Python {platform.python_version()}, numpy {np.__version__}")]
    checks.append(kernels_check())
    if request.benchmark:
        checks.extend(habitat_checks(request.benchmark, request.data_dir, request.split))
    if request.models.reasoner == "openai":
        checks.append(vlm_check(request.models))
    if request.models.detector in MODEL_DETECTORS:
        checks.append(detector_check(request.models))
    if request.models.scorer in ("blip2-itm", "siglip"):
        checks.append(scorer_check(request.models))
    return checks


def format_checks(checks: list[Check]) -> str:
    """The table: status, name, detail, and under each failed check its fix."""
    width = max(len(check.name) for check in checks)
    lines = []
    for check in checks:
        lines.append(f"{'ok  ' if check.ok else 'FAIL'}  {check.name:<{width}}  {check.detail}")
        if not check.ok and check.fix:
            lines.append(f"{'':4}  {'':<{width}}  fix: {check.fix}")
    failed = sum(not check.ok for check in checks)
    lines.append(f"{len(checks) - failed} of {len(checks)} checks passed")
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------- Habitat


def _module_version(name: str) -> tuple[bool, str]:
    """Whether ``name`` imports, and its version (or the import error's first line)."""
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:  # a folder of that name on the path is no installed package
        return False, "not installed"
    try:
        module = importlib.import_module(name)
    except Exception as error:  # a broken install shows as any exception at import
        return False, f"import fails: {_first_line(error)}"
    version = getattr(module, "__version__", None)
    return True, version if isinstance(version, str) else "imports (version unknown)"


def _distribution_version(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


def habitat_checks(benchmark: str, data_dir: Path | None, split: str | None) -> Iterator[Check]:
    """habitat-sim and habitat-lab import; the benchmark's split files, episodes and scenes exist."""
    from drivenav.envs.habitat.benchmarks import BENCHMARKS

    ok, detail = _module_version("habitat_sim")
    yield Check("habitat-sim", ok, detail, HABITAT_SIM_FIX)
    ok, detail = _module_version("habitat")
    if ok:
        release = _distribution_version("habitat-lab") or detail
        tested = "" if release == HABITAT_LAB_VERSION else f"; drivenav is tested with {HABITAT_LAB_VERSION}"
        detail = f"{release}{tested}"
    yield Check("habitat-lab", ok, detail, HABITAT_LAB_FIX)
    bench = BENCHMARKS[benchmark]
    if data_dir is None:
        yield Check("data dir", False, "not given", "pass --data-dir DIR, habitat's data/ folder")
        return
    for name in (split,) if split else bench.splits:
        yield _split_check(benchmark, name, data_dir)
    scene_dataset = data_dir / bench.scene_dataset
    fix = f"download the scenes of {benchmark} (docs/habitat.md) so that this file exists"
    yield Check("scene dataset", scene_dataset.is_file(), str(scene_dataset), fix)


def _split_check(benchmark: str, split: str, data_dir: Path) -> Check:
    from drivenav.envs.habitat.benchmarks import SCENES_DIR
    from drivenav.envs.habitat.layouts import scene_path
    from drivenav.envs.habitat.spec import HabitatSpec

    spec = HabitatSpec(benchmark, split, str(data_dir))
    fix = f"download the {benchmark} episodes (docs/habitat.md) so that {spec.split_file} exists"
    try:
        episodes = spec.episodes()
    except InputError as error:
        return Check(f"split {split}", False, str(error), fix)
    scenes = sorted({episode.scene_id for episode in episodes})
    found = sum(Path(scene_path(scene, str(spec.scenes_dir))).is_file() for scene in scenes)
    detail = f"{len(episodes)} episodes, {len(scenes)} scenes, {found} scene files found under {SCENES_DIR}/"
    scene_fix = f"download the scenes of {benchmark} into {spec.scenes_dir} (docs/habitat.md)"
    return Check(f"split {split}", found == len(scenes), detail, scene_fix)


# ----------------------------------------------------------------------------------------------- models


def _test_frame(sim: SimConfig) -> Observation:
    """A synthetic 640x480 frame: a grey room with a dark doorway (no ground truth)."""
    rgb = np.full((sim.height, sim.width, 3), 170, dtype=np.uint8)
    rgb[sim.height // 4 :, sim.width // 3 : sim.width // 2] = 40
    depth = np.full((sim.height, sim.width), 3.0, dtype=np.float32)
    return Observation(rgb, depth, None, Pose(0.0, 0.0, 0.0), sim.intrinsics, 0, False)


def vlm_check(models: ModelSpec) -> Check:
    """One direction question with one image; the answer must parse in the expected schema as it came."""
    from drivenav.semantics.openai_backend import OpenAIReasoner
    from drivenav.semantics.protocols import Candidate, View

    name = f"VLM {models.vlm_model}"
    fix = "start the server as docs/habitat.md shows (vllm serve ...), or correct --vlm-base-url / --vlm-model"
    try:
        reasoner = OpenAIReasoner(models.vlm_base_url, models.vlm_model, retries=0, timeout=120.0)
        reasoner.check_connection()
    except InputError as error:
        return Check(name, False, str(error), fix)
    frame = _test_frame(SimConfig())
    view = View(1, frame.rgb, None, frame.pose, 0.0, 0.0, 0)
    reasoner.begin_episode("chair", None)
    selection = reasoner.select_direction("chair", [Candidate(1, 0.0, 0.0, 1.0, 10, view)])
    outcome = reasoner.calls[-1].outcome if reasoner.calls else "no call"
    detail = f"{models.vlm_base_url}: one-image answer {outcome} in {reasoner.calls[-1].latency_ms:.0f} ms"
    if selection.fallback or outcome != "ok":
        fix = "the model must answer in the JSON schema of the prompt: serve an instruction-following VLM " + fix
        return Check(name, False, f"{detail} ({selection.note})", fix)
    return Check(name, True, detail)


def detector_check(models: ModelSpec) -> Check:
    """The detector's weights load and it segments one frame."""
    from drivenav.semantics.registry import make_grounder

    def segment_door(grounder: Grounder) -> str:
        grounder.begin_episode(None, 0)
        return f"{len(grounder.segment(_test_frame(SimConfig()), 'door'))} found"

    fix = "pip install 'drivenav[models]' and pass --detector-model with the checkpoint (docs/habitat.md)"
    return _model_check(f"detector {models.detector}", fix, lambda: make_grounder(models), segment_door)


def scorer_check(models: ModelSpec) -> Check:
    """The scorer's weights load and it scores one frame."""
    from drivenav.semantics.registry import SCORER_BACKENDS

    def score_door(scorer: ImageTextScorer) -> str:
        scorer.begin_episode(None)
        return f"score {scorer.score('door', _test_frame(SimConfig())):.3f}"

    fix = "pip install 'drivenav[models]' and pass --scorer-model with the checkpoint (docs/habitat.md)"
    build = SCORER_BACKENDS.get(models.scorer).build
    return _model_check(f"scorer {models.scorer}", fix, lambda: build(models), score_door)


def _model_check(name: str, fix: str, load: Callable[[], Model], use: Callable[[Model], str]) -> Check:
    """Times ``load`` (the weights) and ``use`` (one frame, saying what it found); any failure is the check's."""
    try:
        start = time.perf_counter()
        model = load()
        loaded = time.perf_counter()
        found = use(model)
        done = time.perf_counter()
    except InputError as error:
        return Check(name, False, str(error), fix)
    except Exception as error:  # a broken checkpoint or runtime shows as any exception
        return Check(name, False, f"{type(error).__name__}: {_first_line(error)}", fix)
    detail = f"loaded in {(loaded - start):.1f} s, one frame in {(done - loaded) * 1000:.0f} ms ({found})"
    return Check(name, True, detail)


def _first_line(error: BaseException) -> str:
    return str(error).splitlines()[0] if str(error) else type(error).__name__
