"""Prompt enrichment and cross-frame verification (paper Sec. IV-B, IV-C) on hand-made frames."""

from __future__ import annotations

import numpy as np

from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import Trace
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.semantics.embedded import EmbeddedReasoner
from drivenav.semantics.protocols import Detection, View
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose, SimConfig

SIM = SimConfig()
INTR = CameraIntrinsics.from_hfov(64, 48, 79.0)
LABELS = {1: "toilet", 2: "sofa"}
TRUTH = GroundTruth(LABELS, VOCABULARY)


class PhraseGrounder:
    """Finds instance ``instance`` only for the phrases in ``accepts`` (a detector with a blind spot)."""

    name = "phrase"

    def __init__(self, instance: int, accepts: set[str]) -> None:
        self.instance, self.accepts = instance, accepts
        self.asked: list[str] = []

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        pass

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        self.asked.append(phrase)
        assert observation.semantic is not None
        mask = observation.semantic == self.instance
        return [Detection(mask, 0.9, phrase)] if phrase in self.accepts and mask.any() else []


def _frame(step: int, instance: int) -> Observation:
    semantic = np.zeros((48, 64), dtype=np.int32)
    semantic[20:40, 20:44] = instance
    depth = np.full((48, 64), 3.0, dtype=np.float32)
    depth[20:40, 20:44] = 2.0
    rgb = np.zeros((48, 64, 3), dtype=np.uint8)
    return Observation(rgb, depth, semantic, Pose(0.0, 0.0, 0.0), INTR, step, False)


def _search(grounder: PhraseGrounder, goal: str, verify: bool, enrich: bool = True) -> TargetSearch:
    reasoner = EmbeddedReasoner()
    reasoner.begin_episode(goal, TRUTH)
    search = TargetSearch(SIM, SearchConfig(enrich=enrich, verify=verify), grounder, reasoner)
    search.begin(goal)
    return search


def test_verification_rejects_a_false_positive_into_failed_memory() -> None:
    search = _search(PhraseGrounder(1, {"sofa"}), "sofa", verify=True)  # the detector mistakes the toilet
    trace = Trace()
    search.observe(_frame(0, 1), trace)
    assert search.current() is None
    assert search.verifications["rejected"] == 1
    assert [e.kind for e in trace.events][-1] == "target_rejected"
    search.observe(_frame(5, 1), trace)  # seen again: failed-position memory ignores it
    assert search.current() is None


def test_without_verification_the_false_positive_is_accepted() -> None:
    search = _search(PhraseGrounder(1, {"sofa"}), "sofa", verify=False)
    search.observe(_frame(0, 1), Trace())
    current = search.current()
    assert current is not None and current.status == "accepted"


def test_a_true_detection_is_accepted_by_a_sure_judgement() -> None:
    search = _search(PhraseGrounder(2, {"couch"}), "couch", verify=True)
    search.observe(_frame(0, 2), Trace())
    current = search.current()
    assert current is not None and current.status == "accepted"
    assert search.verifications["accepted"] == 1


def test_enrichment_finds_a_phrase_the_detector_grounds_and_keeps_it() -> None:
    grounder = PhraseGrounder(2, {"sofa"})  # blind to the goal's wording "settee"
    search = _search(grounder, "settee", verify=False)
    frame = _frame(0, 2)
    search.observe(frame, Trace())
    assert search.current() is None
    view = View(0, frame.rgb, frame.semantic, frame.pose, 0.0, 0.0, 0)
    assert search.enrich(frame, view, "shows: sofa", Trace())
    assert search.phrase == "sofa" and 1 <= search.enrich_rounds <= 5
    search.observe(_frame(1, 2), Trace())
    assert grounder.asked[-1] == "sofa"  # the successful phrase is cached for later grounding


def test_enrichment_gives_up_after_five_rounds() -> None:
    grounder = PhraseGrounder(2, set())
    search = _search(grounder, "settee", verify=False)
    frame = _frame(0, 2)
    view = View(0, frame.rgb, frame.semantic, frame.pose, 0.0, 0.0, 0)
    assert not search.enrich(frame, view, "", Trace())
    assert 1 <= search.enrich_rounds <= 5
    assert len(set(search.failed_phrases)) == len(search.failed_phrases) >= 3  # failed phrases fed back
    assert grounder.asked == search.failed_phrases  # every new phrase was tested on the frame
