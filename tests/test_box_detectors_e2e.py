"""OWLv2 with MobileSAM and Grounding DINO end to end in the embedded world: ``eval`` on tiny random checkpoints that
the tests save (the detections are noise: the plumbing, counts and shapes are checked), the same run through a served
grounder giving the same records, ``serve grounder --tiny`` as a command, and a served model's cost beside the
embedded detector (``--detector-shadow-url``).

The checkpoints load with torchvision's image processor only; without torchvision (the dev venv), the in-process
runs accept the PIL processor the tiny checkpoints fall back to (the refusal itself is tested in
test_hf_grounders.py). Runs are 2 episodes of 12 steps on 160 x 120 frames.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("transformers")

import torch

from drivenav.cli import main
from drivenav.semantics import hf_common
from drivenav.semantics.grounder_server import GrounderServer, build_server, served_info, serving
from drivenav.semantics.mobilesam_segmenter import MobileSamSegmenter, save_checkpoint
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.random_grounders import HAS_TORCHVISION, random_grounding_dino, random_mobile_sam, random_owlv2
from drivenav.semantics.serve_config import ServeConfig

RUN = ["eval", "--agent", "directional", "--scenes", "procedural:2", "--episodes", "2", "--seed", "2"]
RUN += ["--max-steps", "12", "--set", "sim.width=160", "--set", "sim.height=120"]
VARYING = {"vlm_latency_ms", "trace"}
LOOPBACK = "tcp://127.0.0.1:*"


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Tiny random OWLv2 (its box regressor zeroed: boxes at the patch priors), Grounding DINO and MobileSAM, saved
    as a user's checkpoints are."""
    root = tmp_path_factory.mktemp("checkpoints")
    torch.manual_seed(0)
    owl, owl_processor = random_owlv2(tiny=True)
    with torch.no_grad():
        owl.box_head.dense2.weight.zero_()
        owl.box_head.dense2.bias.zero_()
    gdino, gdino_processor = random_grounding_dino(tiny=True)
    paths = {"owlv2": root / "owlv2", "grounding-dino": root / "grounding-dino", "mobilesam": root / "mobile_sam.pt"}
    for (model, processor), name in (((owl, owl_processor), "owlv2"), ((gdino, gdino_processor), "grounding-dino")):
        model.save_pretrained(paths[name])
        processor.save_pretrained(paths[name])
    save_checkpoint(random_mobile_sam(tiny=True), "tiny", paths["mobilesam"])
    return paths


@pytest.fixture
def processors(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without torchvision the saved processors load as PIL ones, which the grounders refuse: accepted here."""
    if not HAS_TORCHVISION:
        monkeypatch.setattr(hf_common, "require_fast_image_processor", lambda processor: processor)


@pytest.fixture
def segmented(monkeypatch: pytest.MonkeyPatch) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Every MobileSAM call of the test: the boxes' and the masks' shapes."""
    calls: list[tuple[tuple[int, ...], tuple[int, ...]]] = []
    original = MobileSamSegmenter.segment_boxes

    def recorded(self: MobileSamSegmenter, rgb: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        masks = original(self, rgb, boxes)
        calls.append((boxes.shape, masks.shape))
        return masks

    monkeypatch.setattr(MobileSamSegmenter, "segment_boxes", recorded)
    return calls


def detector_args(detector: str, checkpoints: dict[str, Path]) -> list[str]:
    segmenter = ["--segmenter", "mobilesam", "--segmenter-model", str(checkpoints["mobilesam"])]
    return ["--detector", detector, "--detector-model", str(checkpoints[detector]), *segmenter]


def run_records(out: Path) -> list[dict[str, Any]]:
    lines = (out / "episodes.jsonl").read_text(encoding="utf-8").splitlines()
    records = [{k: v for k, v in json.loads(line).items() if k not in VARYING} for line in lines]
    return sorted(records, key=lambda r: str(r["episode_id"]))


@pytest.mark.parametrize("detector", ["owlv2", "grounding-dino"])
def test_eval_runs_a_box_detector_with_mobilesam_from_saved_checkpoints(
    detector: str,
    checkpoints: dict[str, Path],
    processors: None,
    segmented: list[tuple[tuple[int, ...], tuple[int, ...]]],
    tmp_path: Path,
) -> None:
    assert main([*RUN, *detector_args(detector, checkpoints), "--out", str(tmp_path / "run")]) == 0
    records = run_records(tmp_path / "run")
    assert len(records) == 2 and all(r["error"] == "" for r in records)
    run = json.loads((tmp_path / "run" / "run.json").read_text())["config"]["models"]
    assert (run["detector"], run["segmenter"], run["segmenter_model"]) == (
        detector,
        "mobilesam",
        str(checkpoints["mobilesam"]),
    )
    assert segmented, "MobileSAM never ran"
    assert all(masks == (boxes[0], 120, 160) and boxes[1:] == (4,) for boxes, masks in segmented)
    assert max(boxes[0] for boxes, _ in segmented) > 0


@pytest.mark.parametrize("detector", ["owlv2", "grounding-dino"])
def test_a_served_box_detector_gives_the_in_process_records(
    detector: str, checkpoints: dict[str, Path], processors: None, tmp_path: Path
) -> None:
    """The server ``serve grounder`` builds for the same settings (in this process, on loopback): the in-process
    run's records (fp32, batch one: the same detections)."""
    assert main([*RUN, *detector_args(detector, checkpoints), "--out", str(tmp_path / "local")]) == 0
    spec = ModelSpec(
        detector=detector,
        detector_model=str(checkpoints[detector]),
        segmenter="mobilesam",
        segmenter_model=str(checkpoints["mobilesam"]),
        detector_device="cpu",
    )
    server = build_server(spec, LOOPBACK, None, ServeConfig(batch=1, batch_ms=0.0))
    assert server.info.model.endswith(f" + mobilesam ({checkpoints['mobilesam']})")
    with serving(server) as endpoint:
        assert main([*RUN, "--detector", "remote", "--detector-url", endpoint, "--out", str(tmp_path / "served")]) == 0
    assert run_records(tmp_path / "served") == run_records(tmp_path / "local")
    assert sum(server.batch_sizes.values()) > 0


def test_serve_grounder_tiny_serves_an_eval(tmp_path: Path) -> None:
    """The command: ``serve grounder --tiny`` (Grounding DINO with MobileSAM, random weights) prints its endpoint
    first; an eval grounds through it; SIGTERM stops it, and its last line says what it served."""
    command = [sys.executable, "-m", "drivenav.cli", "serve", "grounder", "--detector", "grounding-dino"]
    command += ["--segmenter", "mobilesam", "--tiny", "--device", "cpu", "--bind", LOOPBACK]
    with (tmp_path / "server.log").open("w") as log:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log, text=True)
        try:
            assert process.stdout is not None
            line = process.stdout.readline()
            assert "serving the grounder grounding-dino (tiny random weights + mobilesam, cpu, float32" in line, line
            endpoint = line.split(" on ")[-1].split()[0]
            assert main([*RUN, "--detector", "remote", "--detector-url", endpoint, "--out", str(tmp_path / "run")]) == 0
        finally:
            process.terminate()
            process.wait(30)
        last = process.stdout.read().strip().splitlines()[-1]
    records = run_records(tmp_path / "run")
    assert len(records) == 2 and all(r["error"] == "" for r in records)
    frames = int(last.split()[1])
    assert last.startswith("served ") and frames > 0 and f"{frames} frames in {frames} batches" in last


@pytest.mark.parametrize("option", ["--tiny", "--random-weights"])
def test_serve_grounder_random_weights_are_for_model_detectors_without_checkpoints(
    option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["serve", "grounder", "--detector", "embedded", option]) == 2
    assert "a model detector (sam3, owlv2, grounding-dino)" in capsys.readouterr().err
    assert main(["serve", "grounder", "--detector", "sam3", option, "--detector-model", "/weights"]) == 2
    assert "no --detector-model or --segmenter-model" in capsys.readouterr().err


def test_a_shadow_grounder_costs_its_forward_and_changes_no_record(tmp_path: Path) -> None:
    """``--detector-shadow-url``: every frame the embedded detector grounds is also sent to a served tiny SAM3 (at
    threshold 0: it finds something everywhere), whose answers are discarded: the records are the plain run's."""
    from drivenav.semantics.random_grounders import random_sam3
    from drivenav.semantics.sam3_grounder import Sam3Grounder

    assert main([*RUN, "--out", str(tmp_path / "plain")]) == 0
    torch.manual_seed(0)
    model, processor = random_sam3(tiny=True)
    sam3 = Sam3Grounder(device="cpu", score_threshold=0.0, model_obj=model, processor_obj=processor)
    config = ServeConfig(batch=1, batch_ms=0.0)
    server = GrounderServer(lambda: sam3, served_info(ModelSpec(detector="sam3"), sam3, config), LOOPBACK, None, config)
    with serving(server) as endpoint:
        assert main([*RUN, "--detector-shadow-url", endpoint, "--out", str(tmp_path / "shadowed")]) == 0
    assert run_records(tmp_path / "shadowed") == run_records(tmp_path / "plain")
    assert sum(server.batch_sizes.values()) > 0
    run = json.loads((tmp_path / "shadowed" / "run.json").read_text())["config"]["models"]
    assert run["detector"] == "embedded" and run["detector_shadow_url"] == endpoint


def test_a_shadow_server_that_does_not_answer_fails_before_any_episode(capsys: pytest.CaptureFixture[str]) -> None:
    args = [*RUN, "--detector-shadow-url", "tcp://127.0.0.1:9", "--set", "models.detector_timeout_s=1"]
    args += ["--out", "never-written"]
    assert main(args) == 2
    error = capsys.readouterr().err
    assert "--detector-shadow-url" in error and len(error.strip().splitlines()) == 1
