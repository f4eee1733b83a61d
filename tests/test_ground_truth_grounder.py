"""The ground-truth grounder on hand-made instance images: synonyms, other categories, tiny masks, no semantics."""

from __future__ import annotations

import numpy as np

from drivenav.envs.vocabulary import VOCABULARY
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.protocols import Grounder, category_key
from drivenav.types import GroundTruth, Observation
from frames import observation_of

H, W = 60, 80
LABELS = {1: "sofa", 2: "Couch", 3: "tv", 4: "sofa", 5: "potted plant", 9: "sofa"}  # 9 is not in the image
TRUTH = GroundTruth(LABELS, VOCABULARY)


def observation(semantic: np.ndarray | None) -> Observation:
    return observation_of(np.zeros((H, W, 3), np.uint8), semantic)


def scene_image() -> np.ndarray:
    sem = np.zeros((H, W), np.int32)
    sem[10:20, 5:25] = 1  # sofa, 200 px
    sem[30:50, 30:60] = 2  # "Couch" label: a sofa too, 600 px
    sem[0:30, 60:80] = 3  # tv, 600 px
    sem[55:60, 0:4] = 4  # sofa, 20 px: too small
    sem[40:52, 0:15] = 5  # plant, 180 px
    return sem


def test_satisfies_grounder_protocol() -> None:
    grounder: Grounder = GroundTruthGrounder(TRUTH)
    assert grounder.name == "ground-truth"


def test_synonym_phrase_finds_every_large_instance_largest_first() -> None:
    sem = scene_image()
    detections = GroundTruthGrounder(TRUTH, min_pixels=50).segment(observation(sem), "couch")
    assert [int(d.mask.sum()) for d in detections] == [600, 200]
    assert np.array_equal(detections[0].mask, sem == 2)
    assert np.array_equal(detections[1].mask, sem == 1)
    assert all(d.score == 1.0 and d.phrase == "couch" and d.mask.dtype == np.bool_ for d in detections)


def test_min_pixels_threshold_is_inclusive() -> None:
    sem = scene_image()
    assert len(GroundTruthGrounder(TRUTH, min_pixels=200).segment(observation(sem), "Sofa")) == 2
    assert len(GroundTruthGrounder(TRUTH, min_pixels=201).segment(observation(sem), "Sofa")) == 1
    assert len(GroundTruthGrounder(TRUTH, min_pixels=20).segment(observation(sem), "sofas")) == 3


def test_other_categories_are_ignored() -> None:
    sem = scene_image()
    grounder = GroundTruthGrounder(TRUTH, min_pixels=50)
    (tv,) = grounder.segment(observation(sem), "television")
    assert np.array_equal(tv.mask, sem == 3)
    assert grounder.segment(observation(sem), "bed") == []


def test_unknown_names_match_verbatim_case_insensitively() -> None:
    assert category_key("  Flux Capacitor ", TRUTH) == "flux capacitor"
    assert category_key("Couch", TRUTH) == "sofa" and category_key("Couch", None) == "couch"  # synonyms: ground truth
    sem = np.zeros((H, W), np.int32)
    sem[:20, :20] = 7
    grounder = GroundTruthGrounder(GroundTruth({7: "Flux Capacitor"}, VOCABULARY), min_pixels=10)
    assert len(grounder.segment(observation(sem), "flux capacitor")) == 1


def test_no_semantic_image() -> None:
    assert GroundTruthGrounder(TRUTH).segment(observation(None), "sofa") == []
