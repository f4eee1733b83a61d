"""``drivenav bench grounder`` on the tiny random models (seconds, no weights), its errors, and ``models.dtype``
(``--dtype``): validated like ``models.detector`` and handed to the grounders.

No timing is asserted: the figures only have to be there, well formed.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from drivenav.cli import build_parser, main
from drivenav.cli.common import given_options
from drivenav.errors import InputError
from drivenav.semantics.model_spec import DTYPES, ModelSpec
from drivenav.semantics.registry import make_grounder
from drivenav.settings import load_settings

KEYS = (
    "median_ms",
    "p90_ms",
    "preprocess_ms",
    "forward_ms",
    "postprocess_ms",
    "segment_ms",
    "detections_per_frame",
    "device",
    "dtype",
    "served_ms_per_frame",
    "gpu_memory_mb",
    "notes",
)


def bench(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    assert main(["bench", "grounder", "--tiny", "--device", "cpu", "--json", *args]) == 0
    result: dict[str, Any] = json.loads(capsys.readouterr().out)
    return result


@pytest.mark.parametrize("detector", ["sam3", "owlv2", "grounding-dino"])
def test_bench_grounder_tiny_prints_the_figures(detector: str, capsys: pytest.CaptureFixture[str]) -> None:
    result = bench(capsys, "--detector", detector, "--frames", "3")
    assert set(KEYS) <= set(result)
    assert result["detector"] == detector and result["frames"] == 3 and result["frame"] == "640x480"
    assert result["device"] == "cpu" and result["dtype"] == "float32"  # auto on the CPU
    assert result["model"] == "tiny test configuration, random weights"
    assert result["served_ms_per_frame"] is None and "served path" in result["notes"]
    assert result["gpu_memory_mb"] is None and result["batch_ms_per_frame"] is None
    stages = [result[key] for key in ("preprocess_ms", "forward_ms", "postprocess_ms")]
    assert all(isinstance(ms, float) and ms > 0.0 for ms in [*stages, result["median_ms"]])
    assert result["p90_ms"] >= result["median_ms"]
    if detector == "sam3":  # its own masks
        assert result["segment_ms"] is None and "boxes to masks" not in result["notes"]
    else:  # the filled box: a part of postprocessing
        assert 0.0 <= result["segment_ms"] <= result["postprocess_ms"]
        assert "boxes to masks: filled-box, a median of" in result["notes"]
        boxes = float(result["notes"].split("a median of ")[1].split(" boxes")[0])
        assert result["detections_per_frame"] <= boxes  # a detection a box at most (random weights: noise boxes)
    assert isinstance(result["detections_per_frame"], float) and result["detections_per_frame"] >= 0.0


@pytest.mark.parametrize("detector", ["owlv2", "grounding-dino"])
def test_bench_grounder_times_mobilesam_apart(detector: str, capsys: pytest.CaptureFixture[str]) -> None:
    result = bench(capsys, "--detector", detector, "--segmenter", "mobilesam", "--frames", "2")
    assert 0.0 < result["segment_ms"] <= result["postprocess_ms"]
    assert "boxes to masks: mobilesam (tiny random weights), a median of " in result["notes"]


def test_bench_grounder_batch_and_dtype(capsys: pytest.CaptureFixture[str]) -> None:
    result = bench(capsys, "--detector", "sam3", "--frames", "2", "--batch", "2", "--dtype", "bfloat16")
    assert result["batch"] == 2 and isinstance(result["batch_ms_per_frame"], float)
    assert result["dtype"] == "bfloat16"


def test_bench_grounder_plain_output_is_one_line_per_figure(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    assert main(["bench", "grounder", "--tiny", "--device", "cpu", "--frames", "1", "--detector", "owlv2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert {line.split(":")[0].strip() for line in lines} >= set(KEYS)


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--detector-model", "/some/dir", "--random-weights"], ["--detector-model", "--random-weights"]),
        (["--frames", "0"], ["--frames", "a positive integer"]),
        (["--batch", "0"], ["--batch"]),
        (["--segmenter", "mobilesam", "--segmenter-model", "/m.pt", "--tiny"], ["--segmenter-model", "--tiny"]),
        (["--detector", "sam3", "--segmenter", "mobilesam"], ["--segmenter", "filled-box with --detector sam3"]),
    ],
)
def test_bench_grounder_bad_options_are_one_line(
    args: list[str], needles: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["bench", "grounder", *args]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1
    assert all(needle in error for needle in needles)


def test_bench_grounder_missing_checkpoint_names_the_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    args = ["bench", "grounder", "--detector", "owlv2", "--device", "cpu", "--detector-model", str(tmp_path / "no")]
    assert main(args) == 2
    assert "--detector-model" in capsys.readouterr().err


# --- models.dtype ---


def test_dtype_defaults_to_auto_and_takes_the_listed_names() -> None:
    assert load_settings("drive-nav").models.dtype == "auto" == ModelSpec().dtype
    for name in DTYPES:
        assert load_settings("drive-nav", options={"models.dtype": name}).models.dtype == name


def test_an_unknown_dtype_is_one_input_error_naming_the_option() -> None:
    with pytest.raises(InputError) as caught:
        load_settings("drive-nav", options={"models.dtype": "fp8"})
    message = str(caught.value)
    assert "'models.dtype'" in message and "--dtype" in message and "'fp8'" in message
    assert "auto, float32, bfloat16, float16" in message


def test_the_dtype_option_sets_models_dtype(capsys: pytest.CaptureFixture[str]) -> None:
    args = build_parser().parse_args(
        ["eval", "--agent", "oracle", "--episodes", "1", "--out", "run", "--dtype", "bfloat16"]
    )
    assert given_options(args)["models.dtype"] == "bfloat16"
    assert main(["config", "show", "--set", "models.dtype=bfloat16"]) == 0
    assert "dtype: bfloat16" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("detector", "module", "class_name"),
    [
        ("sam3", "sam3_grounder", "Sam3Grounder"),
        ("owlv2", "owlv2_grounder", "Owlv2Grounder"),
        ("grounding-dino", "grounding_dino_grounder", "GroundingDinoGrounder"),
    ],
)
@pytest.mark.parametrize("compile_models", [False, True])
def test_the_registry_hands_the_dtype_and_compile_to_the_grounder(
    detector: str, module: str, class_name: str, compile_models: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("transformers")
    seen: dict[str, Any] = {}

    class Recorder:
        name = "recorder"  # a grounder's name (the protocol's), read by the output check that wraps it

        def __init__(self, model: str, **kwargs: Any) -> None:
            seen.update(kwargs, model=model)

    monkeypatch.setattr(f"drivenav.semantics.{module}.{class_name}", Recorder)
    make_grounder(ModelSpec(detector=detector, detector_model="/weights", dtype="float16", compile=compile_models))
    segmenter = seen.pop("segmenter", None)
    assert seen == {"model": "/weights", "dtype": "float16", "compile_backend": "inductor" if compile_models else ""}
    assert (type(segmenter).__name__ if segmenter else None) == (None if detector == "sam3" else "FilledBoxSegmenter")


def test_the_compile_option_sets_models_compile(capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    assert "models.compile" not in given_options(parser.parse_args([*EVAL, "--out", "run"]))
    args = parser.parse_args([*EVAL, "--out", "run", "--compile", "--segmenter", "mobilesam", "--segmenter-model", "m"])
    assert given_options(args) == {
        "models.compile": True,
        "models.segmenter": "mobilesam",
        "models.segmenter_model": "m",
    }
    assert load_settings("drive-nav").models.compile is False
    assert main(["config", "show", "--set", "models.compile=true"]) == 0
    assert "compile: true" in capsys.readouterr().out


EVAL = ["eval", "--agent", "oracle", "--episodes", "1"]
