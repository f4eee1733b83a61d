"""The embedded reasoner: direction choice, prompt proposal and verification from the views' instance labels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from drivenav.envs.vocabulary import VOCABULARY
from drivenav.semantics.embedded import EmbeddedReasoner, EmbeddedReasonerConfig, label_areas
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.protocols import Candidate, Reasoner, VerificationFrame, View
from drivenav.types import GroundTruth, Pose

H, W = 480, 640
LABELS = {1: "sofa", 2: "lamp", 3: "toilet", 4: "chair", 5: "mini fridge", 6: "pillow", 7: "couch", 8: "tv"}
TRUTH = GroundTruth(LABELS, VOCABULARY)

Box = tuple[int, int, int, int, int]  # instance id, row0, row1, col0, col1


def semantic(*boxes: Box) -> NDArray[np.int32]:
    image = np.zeros((H, W), dtype=np.int32)
    for instance, r0, r1, c0, c1 in boxes:
        image[r0:r1, c0:c1] = instance
    return image


def view(label: int, *boxes: Box) -> View:
    return View(
        label=label,
        rgb=np.zeros((H, W, 3), dtype=np.uint8),
        semantic=semantic(*boxes),
        pose=Pose(0.0, 0.0, 0.0),
        bearing=0.0,
        error=0.0,
        step=0,
    )


def cand(
    label: int, *boxes: Box, cells: int = 60, time: float = 3.0, turn: float = 0.0, seen: bool = True
) -> Candidate:
    return Candidate(label, turn, turn, time, cells, view(label, *boxes) if seen else None)


def reasoner(goal: str = "sofa") -> EmbeddedReasoner:
    r = EmbeddedReasoner(default_embedder())
    r.begin_episode(goal, TRUTH)
    return r


def frame(mask_box: tuple[int, int, int, int], *boxes: Box, with_semantic: bool = True) -> VerificationFrame:
    mask = np.zeros((H, W), dtype=bool)
    r0, r1, c0, c1 = mask_box
    mask[r0:r1, c0:c1] = True
    return VerificationFrame(
        rgb=np.zeros((H, W, 3), dtype=np.uint8),
        mask=mask,
        overlay=np.zeros((H, W, 3), dtype=np.uint8),
        semantic=semantic(*boxes) if with_semantic else None,
        pose=Pose(0.0, 0.0, 0.0),
        step=0,
    )


SOFA = (1, 200, 300, 100, 300)  # 20,000 px
LAMP = (2, 100, 200, 400, 450)  # 5,000 px
TOILET = (3, 250, 400, 300, 400)  # 15,000 px
PILLOW = (6, 250, 300, 350, 450)  # 5,000 px


def test_satisfies_reasoner_protocol() -> None:
    r: Reasoner = reasoner()
    assert r.name == "embedded"


def test_label_areas_sum_instances_and_drop_tiny_ones() -> None:
    image = semantic(SOFA, (7, 0, 10, 0, 10), (8, 400, 410, 0, 20), (9, 0, 50, 600, 640))
    labels = {1: "sofa", 7: "sofa", 8: "tv"}  # id 9 has no label: not recognisable
    assert label_areas(image, labels, 150) == [("sofa", 20_100), ("tv", 200)]
    assert label_areas(image, labels, 201) == [("sofa", 20_100)]


def test_the_view_showing_the_target_wins_over_a_bigger_empty_frontier() -> None:
    candidates = [cand(1, cells=400, time=1.0), cand(2, LAMP, SOFA, cells=5, time=12.0, turn=2.5), cand(3, TOILET)]
    selection = reasoner().select_direction("sofa", candidates)
    assert selection.label == 2
    assert selection.target_visible and selection.target_label == 2


def test_a_synonym_label_is_the_target() -> None:
    selection = reasoner().select_direction("sofa", [cand(1), cand(2, (7, 0, 100, 0, 100))])
    assert selection.target_visible and selection.target_label == 2


def test_target_label_is_the_view_with_the_largest_target_area() -> None:
    small, large = (1, 0, 50, 0, 50), (1, 0, 150, 0, 150)
    candidates = [cand(1, small, turn=0.1), cand(2, large, turn=2.0), cand(3, LAMP)]
    selection = reasoner().select_direction("couch", candidates)
    assert selection.label == selection.target_label == 2


def test_no_target_in_any_view_means_not_visible() -> None:
    tiny_sofa = (1, 0, 10, 0, 10)  # 100 px, under min_pixels
    selection = reasoner().select_direction("sofa", [cand(1, LAMP), cand(2, TOILET), cand(3, tiny_sofa)])
    assert not selection.target_visible and selection.target_label is None
    selection = reasoner().select_direction("sofa", [cand(1, seen=False), cand(2, seen=False)])
    assert not selection.target_visible and selection.target_label is None


def test_a_related_object_beats_an_empty_view_and_an_unrelated_one() -> None:
    r = reasoner("bed")
    candidates = [cand(1), cand(2, TOILET), cand(3, PILLOW)]
    assert r.select_direction("bed", candidates).label == 3
    assert r.select_direction("bed", candidates[::-1]).label == 3


def test_an_empty_corridor_is_not_worthless() -> None:
    r = reasoner("bed")
    assert r.select_direction("bed", [cand(1, cells=300, time=2.0), cand(2, TOILET, cells=3, time=2.0)]).label == 1
    # Without views only the geometry counts: more frontier wins, then the smaller turn.
    no_views = [
        cand(1, cells=40, seen=False),
        cand(2, cells=90, turn=0.5, seen=False),
        cand(3, cells=90, turn=-0.2, seen=False),
    ]
    assert r.select_direction("bed", no_views).label == 3


def test_unreachable_empty_direction_scores_nothing() -> None:
    candidates = [cand(1, cells=500, time=math.inf), cand(2, cells=5, time=3.0)]
    assert reasoner().select_direction("sofa", candidates).label == 2


def test_descriptions_list_labels_by_area() -> None:
    candidates = [cand(1, LAMP, SOFA, (8, 0, 20, 0, 20)), cand(2), cand(3, seen=False)]
    selection = reasoner().select_direction("tv", candidates)
    assert selection.descriptions == {1: "shows: sofa, lamp, tv", 2: "shows: nothing recognisable"}


def test_selection_is_deterministic_and_order_free() -> None:
    candidates = [cand(k, LAMP, turn=0.3 * (-1) ** k) for k in range(4, 0, -1)]
    first = reasoner().select_direction("sofa", candidates)
    assert first == reasoner().select_direction("sofa", candidates[::-1])
    assert first.label == 1  # equal scores and equal |turn|: the smaller label


def test_one_model_call_per_question() -> None:
    r = reasoner()
    r.select_direction("sofa", [cand(1)])
    r.propose_prompt("sofa", view(1, SOFA), "shows: sofa", [])
    r.verify("sofa", frame((200, 300, 100, 300), SOFA), [])
    assert [(c.kind, c.outcome) for c in r.calls] == [
        ("select_direction", "ok"),
        ("propose_prompt", "ok"),
        ("verify", "ok"),
    ]
    assert all(c.latency_ms >= 0.0 for c in r.calls)
    r.begin_episode("tv", TRUTH)
    assert r.calls == []


def test_propose_prompt_names_the_visible_target_and_skips_failed_phrases() -> None:
    r = reasoner("settee")
    shown = view(1, LAMP, (7, 0, 150, 0, 150), SOFA)  # couch (22,500 px) and sofa (20,000 px)
    assert r.propose_prompt("settee", shown, "", []).phrase == "couch"
    assert r.propose_prompt("settee", shown, "", [" COUCH"]).phrase == "sofa"
    # Nothing target-like left in view: the vocabulary's name, then synonyms not yet tried.
    assert r.propose_prompt("settee", shown, "", ["couch", "Sofa"]).phrase == "settee"
    assert r.propose_prompt("settee", shown, "", ["couch", "sofa", "settee"]).phrase == "loveseat"


def test_propose_prompt_never_names_an_unrelated_object() -> None:
    r = reasoner("refrigerator")
    phrase = r.propose_prompt("refrigerator", view(1, LAMP, TOILET), "shows: toilet, lamp", []).phrase
    assert phrase == "refrigerator"
    assert r.propose_prompt("fridge", view(1, (5, 0, 100, 0, 100)), "", []).phrase == "mini fridge"


def test_propose_prompt_outside_the_vocabulary_falls_back_to_the_goal() -> None:
    assert reasoner("zebra").propose_prompt("zebra", view(1, LAMP), "", []).phrase == "zebra"


@pytest.mark.parametrize(
    ("goal", "box", "expected"),
    [
        ("sofa", SOFA, "sure"),
        ("couch", SOFA, "sure"),
        ("refrigerator", (5, 200, 300, 100, 300), "uncertain"),
        ("armchair", (4, 200, 300, 100, 300), "not"),
        ("sofa", (3, 200, 300, 100, 300), "not"),
    ],
)
def test_verify_judges_the_label_under_the_mask(goal: str, box: Box, expected: str) -> None:
    assert reasoner(goal).verify(goal, frame((200, 300, 100, 300), box, LAMP), []).judgement == expected


def test_verify_takes_the_majority_instance_under_the_mask() -> None:
    # The mask covers 20,000 sofa pixels and 5,000 toilet pixels.
    mask_box = (200, 300, 100, 350)
    boxes = (SOFA, (3, 200, 300, 300, 350))
    assert reasoner().verify("sofa", frame(mask_box, *boxes), []).judgement == "sure"
    assert reasoner("toilet").verify("toilet", frame(mask_box, *boxes), []).judgement == "not"


def test_verify_background_and_blind_cases() -> None:
    r = reasoner()
    assert r.verify("sofa", frame((0, 50, 0, 50), SOFA), []).judgement == "not"
    assert r.verify("sofa", frame((0, 0, 0, 0), SOFA), []).judgement == "not"
    assert r.verify("sofa", frame((200, 300, 100, 300), SOFA, with_semantic=False), []).judgement == "uncertain"


def test_without_labels_nothing_is_recognised() -> None:
    r = EmbeddedReasoner(default_embedder())
    r.begin_episode("sofa", None)
    selection = r.select_direction("sofa", [cand(1, SOFA), cand(2, cells=200)])
    assert not selection.target_visible and selection.label == 2


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="min_pixels"):
        EmbeddedReasonerConfig(min_pixels=0)
    with pytest.raises(ValueError, match="uncertain_similarity"):
        EmbeddedReasonerConfig(uncertain_similarity=0.9, sure_similarity=0.8)
    with pytest.raises(ValueError, match="distance_scale"):
        EmbeddedReasonerConfig(distance_scale=math.nan)
