"""The floor question answered by the embedded reasoner from what a floor's views show (docs/floors.md).

The OpenAI-compatible backend's floor prompt is tested in tests/test_openai_backend.py, its record and replay in
tests/test_replay.py.
"""

from __future__ import annotations

import pytest

from drivenav.envs.vocabulary import VOCABULARY
from drivenav.semantics.embedded import EmbeddedReasoner, EmbeddedReasonerConfig
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.protocols import FloorGuess, View
from drivenav.types import GroundTruth
from test_embedded_reasoner import view

LABELS = {1: "refrigerator", 2: "oven", 3: "sink", 4: "sofa", 5: "coffee table", 6: "tv", 7: "bed"}
TRUTH = GroundTruth(LABELS, VOCABULARY)

KITCHEN = view(1, (1, 50, 250, 0, 150), (2, 250, 400, 150, 300), (3, 200, 300, 400, 550))
LIVING_ROOM = view(2, (4, 200, 350, 50, 350), (5, 350, 420, 150, 300), (6, 80, 200, 400, 560))
BEDROOM = view(3, (7, 250, 420, 100, 500))


@pytest.mark.parametrize(
    ("views", "expected"),
    [
        # refrigerator and oven read as a kitchen, the sink as a bathroom, the coffee table as a dining room (the
        # sofa and tv as no room): three rooms and none a bedroom
        ([KITCHEN, LIVING_ROOM], "other"),
        ([KITCHEN, LIVING_ROOM, BEDROOM], "this"),  # a bed seen
        ([BEDROOM], "this"),
        ([view(4, (1, 50, 250, 0, 150), (2, 250, 400, 150, 300))], "unsure"),  # one room, a kitchen
        ([], "unsure"),
    ],
)
def test_the_embedded_reasoner_judges_a_floor_by_the_rooms_its_views_show(
    views: list[View], expected: FloorGuess
) -> None:
    reasoner = EmbeddedReasoner(default_embedder())
    reasoner.begin_episode("bed", TRUTH)
    judgement = reasoner.judge_floor("bed", views)
    assert (judgement.guess, judgement.fallback) == (expected, False)
    assert [(c.kind, c.outcome) for c in reasoner.calls] == [("judge_floor", "ok")]


UPSTAIRS = {1: "desk", 2: "toilet", 3: "bed", 4: "coffee table", 5: "toy"}
OFFICE = view(1, (1, 200, 400, 100, 400))
BATHROOM = view(2, (2, 250, 420, 200, 400))
A_BEDROOM = view(3, (3, 250, 420, 100, 500))
A_LIVING_ROOM = view(4, (4, 300, 420, 150, 450))
PLAYROOM = view(5, (5, 300, 420, 150, 450))


@pytest.mark.parametrize(
    ("goal", "views", "knowledge", "expected"),
    [
        # an office, a bathroom and a bedroom, no kitchen: the dishwasher is on another floor
        ("dishwasher", [OFFICE, BATHROOM, A_BEDROOM], True, "other"),
        # a living room instead of the office: the kitchen is kept on the living room's floor, not yet seen
        ("dishwasher", [A_LIVING_ROOM, BATHROOM, A_BEDROOM], True, "unsure"),
        # an office, a bedroom and a playroom, no bathroom seen: every floor has one
        ("toilet", [OFFICE, A_BEDROOM, PLAYROOM], True, "unsure"),
        # without that knowledge the three rooms hold none of the goal's
        ("dishwasher", [A_LIVING_ROOM, BATHROOM, A_BEDROOM], False, "other"),
        ("toilet", [OFFICE, A_BEDROOM, PLAYROOM], False, "other"),
    ],
)
def test_the_floor_question_completes_the_rooms_shown_with_what_every_home_has(
    goal: str, views: list[View], knowledge: bool, expected: FloorGuess
) -> None:
    config = EmbeddedReasonerConfig() if knowledge else EmbeddedReasonerConfig(floor_together=(), floor_everywhere=())
    reasoner = EmbeddedReasoner(default_embedder(), config)
    reasoner.begin_episode(goal, GroundTruth(UPSTAIRS, VOCABULARY))
    judgement = reasoner.judge_floor(goal, views)
    assert judgement.guess == expected
    assert ("with the rooms this floor has unseen" in judgement.note) == (expected == "unsure")
