"""Hostile model outputs (issue 60): what an in-process or served model returns is checked at the protocol boundary
(:mod:`drivenav.semantics.checked`). A scorer's NaN, infinity, 1e300 or 2 is a logged ``fallback`` answering 0; a
grounder's detection scored NaN, 5 or -0.1, or with a mask of another size, is dropped; an integer mask is made
boolean once; at most ``models.max_detections`` detections a frame are kept. The fake models are throwaway
backends (conftest's ``plug_in``) or wrap the embedded ones; the served grounder drops what the in-process one does.
"""

from __future__ import annotations

import logging
import math
import sys
import types
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from conftest import plug_in
from drivenav.errors import InputError
from drivenav.semantics.checked import DetectionCheck
from drivenav.semantics.embedded_scorer import EmbeddedScorer
from drivenav.semantics.grounder_server import GrounderServer, served_info, serving
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import Detection, ModelCall, ScorePrompt
from drivenav.semantics.registry import Backend, make_grounder, make_scorer
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.serve_config import DEFAULT_MAX_DETECTIONS, ServeConfig
from drivenav.semantics.served import GrounderClient, detections_reply, read_detections
from drivenav.settings import load_settings
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose
from drivenav.wire.client import ClientConfig

H, W = 24, 32
HOSTILE_SIMILARITIES = (math.nan, math.inf, -math.inf, 1e300, -1e300, 2.0, "0.5", None)


def frame() -> Observation:
    return Observation(
        rgb=np.zeros((H, W, 3), dtype=np.uint8),
        depth=np.full((H, W), 2.0, dtype=np.float32),
        semantic=None,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(W, H, 79.0),
        step=0,
        collided=False,
    )


def box(value: int = 1, dtype: type = bool) -> np.ndarray:
    mask = np.zeros((H, W), dtype=dtype)
    mask[4:12, 8:20] = value
    return mask


class FixedScorer:
    """A scorer plug-in answering ``value`` to every frame (and recording its call as ``ok``)."""

    name = "fixed"

    def __init__(self, value: object) -> None:
        self.value = value
        self.calls: list[ModelCall] = []

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.calls = []

    def score(self, goal: str, observation: Observation, prompt: ScorePrompt | None = None) -> float:
        self.calls.append(ModelCall("score", 2.5, "ok"))
        return self.value  # type: ignore[return-value]


class FixedGrounder:
    """A grounder plug-in answering ``detections`` to every frame."""

    name = "fixed"

    def __init__(self, detections: Sequence[object]) -> None:
        self.detections = list(detections)

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Nothing to begin."""

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        return list(self.detections)  # type: ignore[arg-type]


@pytest.fixture
def hostile(monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    """The throwaway backends ``fixed`` (a scorer and a grounder of module ``hostile_models``), answering what the
    test puts into the returned dictionary (``score``, ``detections``)."""
    answers: dict[str, object] = {}
    module = types.ModuleType("hostile_models")
    module.SCORER = Backend(lambda spec: FixedScorer(answers["score"]))  # type: ignore[attr-defined]
    module.GROUNDER = Backend(lambda spec: FixedGrounder(answers["detections"]))  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "hostile_models", module)
    plug_in(
        monkeypatch,
        ("drivenav.scorers", "fixed", "hostile_models:SCORER", "hostile-models"),
        ("drivenav.grounders", "fixed", "hostile_models:GROUNDER", "hostile-models"),
    )
    return answers


# --- the scorer -----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", HOSTILE_SIMILARITIES)
def test_a_scorer_answer_out_of_range_is_a_logged_fallback_answering_0(
    value: object, hostile: dict[str, object], caplog: pytest.LogCaptureFixture
) -> None:
    hostile["score"] = value
    scorer = make_scorer(ModelSpec(scorer="fixed"))
    scorer.begin_episode(None)
    with caplog.at_level(logging.WARNING, "drivenav.semantics.checked"):
        assert [scorer.score("chair", frame()) for _ in range(3)] == [0.0, 0.0, 0.0]
    assert [(c.kind, c.latency_ms, c.outcome) for c in scorer.calls] == [("score", 2.5, "fallback")] * 3
    assert len(caplog.records) == 1 and "fixed (scorer)" in caplog.text  # once, not every frame


@pytest.mark.parametrize("value", [-1.0, 0.0, 0.37, 1.0, 1.0000001])
def test_a_scorer_answer_in_range_is_kept(value: float, hostile: dict[str, object]) -> None:
    hostile["score"] = value
    scorer = make_scorer(ModelSpec(scorer="fixed"))
    assert scorer.score("chair", frame()) == value
    assert [c.outcome for c in scorer.calls] == ["ok"]


def test_a_recorded_score_is_the_checked_one(hostile: dict[str, object], tmp_path: Path) -> None:
    """A recording holds the fallback 0, which the replay reads (it refuses |score| > 1)."""
    hostile["score"] = math.nan
    record = tmp_path / "calls.jsonl"
    assert make_scorer(ModelSpec(scorer="fixed", vlm_record=str(record))).score("chair", frame()) == 0.0
    assert make_scorer(ModelSpec(scorer="replay", vlm_replay=str(record))).score("chair", frame()) == 0.0


def test_the_embedded_scorer_is_unchanged() -> None:
    """The wrapper answers what the built-in scorer does (no frame here: a neutral 0, an ``ok`` call)."""
    scorer = make_scorer(ModelSpec())
    assert scorer.name == EmbeddedScorer.name and scorer.score("chair", frame()) == 0.0
    assert [c.outcome for c in scorer.calls] == ["ok"]


# --- the grounder ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("score", [math.nan, math.inf, -math.inf, 5.0, -0.1, 1e300, "0.9", None])
def test_a_detection_scored_out_of_range_is_dropped(
    score: object, hostile: dict[str, object], caplog: pytest.LogCaptureFixture
) -> None:
    good = Detection(box(), 0.8, "chair")
    hostile["detections"] = [Detection(box(), score, "chair"), good]  # type: ignore[arg-type]
    grounder = make_grounder(ModelSpec(detector="fixed"))
    with caplog.at_level(logging.WARNING, "drivenav.semantics.checked"):
        assert grounder.segment(frame(), "chair") == [good]
    assert "score not in [0, 1] dropped" in caplog.text


def test_an_integer_mask_is_made_boolean_once(hostile: dict[str, object]) -> None:
    hostile["detections"] = [Detection(box(1, np.int64), 0.8, "chair"), Detection(box(255, np.uint8), 0.7, "chair")]
    found = make_grounder(ModelSpec(detector="fixed")).segment(frame(), "chair")
    assert [d.mask.dtype for d in found] == [np.bool_, np.bool_]
    assert all(np.array_equal(d.mask, box()) for d in found) and [d.score for d in found] == [0.8, 0.7]


@pytest.mark.parametrize(
    "mask",
    [box(1, np.float32), np.ones((H, W + 1), dtype=bool), np.ones((H, W, 3), dtype=bool), box().tolist(), None],
    ids=["float", "wider", "three-channel", "list", "none"],
)
def test_a_mask_that_is_not_a_frame_of_pixels_is_dropped(mask: object, hostile: dict[str, object]) -> None:
    good = Detection(box(), 0.8, "chair")
    hostile["detections"] = [Detection(mask, 0.9, "chair"), good, "not a detection"]  # type: ignore[arg-type]
    assert make_grounder(ModelSpec(detector="fixed")).segment(frame(), "chair") == [good]


def test_the_detections_of_a_frame_are_capped_best_first_in_the_models_order(hostile: dict[str, object]) -> None:
    full = np.ones((H, W), dtype=bool)
    scores = [0.1, 0.9, 0.5, 0.9, 0.7, 0.2]
    hostile["detections"] = [Detection(full, s, "chair") for s in scores]
    found = make_grounder(ModelSpec(detector="fixed", max_detections=3)).segment(frame(), "chair")
    assert [d.score for d in found] == [0.9, 0.9, 0.7]
    hostile["detections"] = [Detection(full, 0.5, "chair")] * 500
    assert len(make_grounder(ModelSpec(detector="fixed")).segment(frame(), "chair")) == DEFAULT_MAX_DETECTIONS


@pytest.mark.parametrize("value", [0, -1, 10_001, 2.5])
def test_max_detections_is_a_bounded_count(value: object) -> None:
    with pytest.raises(InputError, match=r"models\.max_detections"):
        load_settings("vlfm", options={"models.max_detections": value})


def test_the_built_in_grounders_answers_pass_unchanged() -> None:
    """The checked ground-truth grounder gives the very detections (the same objects) of the bare one."""
    from drivenav.semantics.ground_truth import GroundTruthGrounder

    observation = frame()
    semantic = np.zeros((H, W), dtype=np.int32)
    semantic[2:20, 3:30] = 7
    observation = Observation(
        observation.rgb, observation.depth, semantic, observation.pose, observation.intrinsics, 0, False
    )
    truth = GroundTruth({7: "chair"})
    bare, checked = GroundTruthGrounder(), make_grounder(ModelSpec(detector="ground-truth"))
    bare.begin_episode(truth, 0)
    checked.begin_episode(truth, 0)
    expected = bare.segment(observation, "chair")
    found = checked.segment(observation, "chair")
    assert len(found) == 1 and found[0].score == expected[0].score and np.array_equal(found[0].mask, expected[0].mask)


# --- served: the same checks ----------------------------------------------------------------------------------------


def hostile_detections() -> list[Detection]:
    return [
        Detection(box(), math.nan, "chair"),
        Detection(box(), 5.0, "chair"),
        Detection(box(1, np.uint8), 0.6, "chair"),
        Detection(box(), 0.8, "chair"),
    ]


def in_process(detections: Callable[[], list[Detection]]) -> list[Detection]:
    return DetectionCheck("fixed").checked(detections(), (H, W))


def test_a_served_grounder_drops_what_the_in_process_one_does() -> None:
    config = ServeConfig(batch=1)
    grounder = FixedGrounder(hostile_detections())
    info = served_info(ModelSpec(detector="sam3"), grounder, config)  # a model server: one shared grounder
    server = GrounderServer(lambda: grounder, info, "tcp://127.0.0.1:*", None, config)
    with serving(server) as endpoint:
        connection = GrounderClient(endpoint, None, ClientConfig(timeout_s=20.0, retries=0, heartbeat_s=0.1))
        try:
            remote = RemoteGrounder(connection, info)
            remote.begin_episode(None, 0)
            found = remote.segment(frame(), "chair")
        finally:
            connection.close()
    expected = in_process(hostile_detections)
    assert [d.score for d in found] == [d.score for d in expected] == [0.6, 0.8]
    assert all(np.array_equal(a.mask, b.mask) for a, b in zip(found, expected, strict=True))


def test_a_reply_with_a_nan_score_is_checked_as_in_process_not_refused() -> None:
    """Another server's NaN reaches the client's check (the remote grounder is built checked), which drops it."""
    reply = detections_reply(
        "r1", "chair", [Detection(box(), math.nan, "chair"), Detection(box(), 0.8, "chair")], (H, W)
    )
    read = read_detections(reply, "chair", (H, W))
    assert [d.score for d in DetectionCheck("remote").checked(read, (H, W))] == [0.8]
